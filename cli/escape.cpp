#include "escape.h"

#include <cstdio>

namespace bloomref::escape {
namespace {

std::string hex_byte(unsigned char c) {
  char b[8];
  std::snprintf(b, sizeof b, "\\x%02X", c);
  return b;
}

// The length of the well-formed UTF-8 sequence at s[i] (RFC 3629, Unicode table 3-7), or 0.
std::size_t sequence_at(std::string_view s, std::size_t i, char32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char c = b(0);
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  std::size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;
  if (c >= 0xC2 && c <= 0xDF) n = 2;
  else if (c == 0xE0) n = 3, lo = 0xA0;
  else if (c == 0xED) n = 3, hi = 0x9F;  // no surrogates
  else if (c >= 0xE1 && c <= 0xEF) n = 3;
  else if (c == 0xF0) n = 4, lo = 0x90;
  else if (c >= 0xF1 && c <= 0xF3) n = 4;
  else if (c == 0xF4) n = 4, hi = 0x8F;  // nothing past U+10FFFF
  else return 0;
  if (i + n > s.size()) return 0;
  if (b(1) < lo || b(1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k)
    if (b(k) < 0x80 || b(k) > 0xBF) return 0;
  cp = n == 2 ? c & 0x1F : n == 3 ? c & 0x0F : c & 0x07;
  for (std::size_t k = 1; k < n; ++k) cp = (cp << 6) | (b(k) & 0x3F);
  return n;
}

// Calls put(code point, its bytes) for each well-formed character and bad(byte) for each byte
// that is not part of one.
template <class Put, class Bad>
void each(std::string_view s, Put put, Bad bad) {
  for (std::size_t i = 0; i < s.size();) {
    char32_t cp = 0;
    const std::size_t n = sequence_at(s, i, cp);
    if (n == 0) {
      bad(static_cast<unsigned char>(s[i]));
      ++i;
      continue;
    }
    put(cp, s.substr(i, n));
    i += n;
  }
}

// & < > as the references HTML, XML and Markdown share; false for any other character.
bool put_markup(char32_t cp, std::string& o) {
  switch (cp) {
    case '&': o += "&amp;"; return true;
    case '<': o += "&lt;"; return true;
    case '>': o += "&gt;"; return true;
    default: return false;
  }
}

}  // namespace

std::string utf8(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  each(s, [&](char32_t, std::string_view bytes) { o += bytes; },
       [&](unsigned char c) { o += hex_byte(c); });
  return o;
}

std::string html(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  each(s,
       [&](char32_t cp, std::string_view bytes) {
         if (put_markup(cp, o)) return;
         switch (cp) {
           case '"': o += "&quot;"; break;
           case '\'': o += "&#39;"; break;
           default:
             if ((cp < 0x20 && cp != '\t' && cp != '\n') || cp == 0x7F || (cp >= 0x80 && cp < 0xA0))
               o += hex_byte(static_cast<unsigned char>(cp));
             else
               o += bytes;
         }
       },
       [&](unsigned char c) { o += hex_byte(c); });
  return o;
}

std::string url(std::string_view path) {
  // ':' is encoded, so no scheme can start it; a leading "//" (another host) becomes "/".
  while (path.size() > 1 && path[0] == '/' && path[1] == '/') path.remove_prefix(1);
  std::string enc;
  for (unsigned char c : path) {
    const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      c == '-' || c == '.' || c == '_' || c == '~' || c == '/';
    if (keep) {
      enc += static_cast<char>(c);
    } else {
      char b[4];
      std::snprintf(b, sizeof b, "%%%02X", c);
      enc += b;
    }
  }
  return html(enc);
}

std::string xml(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  each(s,
       [&](char32_t cp, std::string_view bytes) {
         if (put_markup(cp, o)) return;
         switch (cp) {
           case '"': o += "&quot;"; break;
           case '\'': o += "&apos;"; break;
           case '\t': o += "&#9;"; break;
           case '\n': o += "&#10;"; break;
           case '\r': o += "&#13;"; break;
           default:
             if (cp < 0x20) o += hex_byte(static_cast<unsigned char>(cp));
             else if (cp == 0xFFFE || cp == 0xFFFF) o += "\\u" + std::string(cp == 0xFFFE ? "FFFE" : "FFFF");
             else o += bytes;
         }
       },
       [&](unsigned char c) { o += hex_byte(c); });
  return o;
}

std::string markdown_cell(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  each(s,
       [&](char32_t cp, std::string_view bytes) {
         if (put_markup(cp, o)) return;
         switch (cp) {
           case '\\': case '|': case '`': case '*': case '_': case '[': case ']': case '~':
           case '!': case '#':
             o += '\\';
             o += static_cast<char>(cp);
             break;
           default:
             if (cp < 0x20 || cp == 0x7F || (cp >= 0x80 && cp < 0xA0)) o += ' ';
             else o += bytes;
         }
       },
       [&](unsigned char c) { o += "\\\\" + hex_byte(c).substr(1); });
  return o;
}

std::string markdown_code(std::string_view s) {
  std::string o;
  each(s,
       [&](char32_t cp, std::string_view bytes) {
         if (cp == '`') o += '\'';
         else if (cp == '|') o += "\\|";
         else if (cp < 0x20 || cp == 0x7F || (cp >= 0x80 && cp < 0xA0)) o += ' ';
         else o += bytes;
       },
       [&](unsigned char c) { o += hex_byte(c); });
  return "`" + o + "`";
}

nlohmann::ordered_json json_valid(const nlohmann::ordered_json& j) {
  if (j.is_string()) return utf8(j.get_ref<const std::string&>());
  if (j.is_array()) {
    nlohmann::ordered_json a = nlohmann::ordered_json::array();
    for (const auto& v : j) a.push_back(json_valid(v));
    return a;
  }
  if (j.is_object()) {
    nlohmann::ordered_json o = nlohmann::ordered_json::object();
    for (const auto& [k, v] : j.items()) o[utf8(k)] = json_valid(v);
    return o;
  }
  return j;
}

std::string json_text(const nlohmann::ordered_json& j, int indent) {
  return json_valid(j).dump(indent);
}

}  // namespace bloomref::escape
