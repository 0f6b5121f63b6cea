#include "check/json_fields.h"

#include <cctype>
#include <cstdlib>

#include "bloomref/error.h"

namespace bloomref::cli::json_fields {
namespace {

template <class Json>
void keys_of(const std::string& file, const std::string& field, const Json& obj,
             const std::set<std::string>& keys) {
  if (!obj.is_object()) bad(file, field, "must be a JSON object");
  for (const auto& [key, value] : obj.items())
    if (!keys.count(key)) {
      std::string known;
      for (const std::string& k : keys) known += (known.empty() ? "" : ", ") + k;
      bad(file, (field == "(top level)" ? "" : field + ".") + key,
          "is not a known key here (known: " + known + ")");
    }
}

}  // namespace

void bad(const std::string& file, const std::string& field, const std::string& why) {
  throw InputError(file, field + ": " + why);
}

void only_keys(const std::string& file, const std::string& field, const nlohmann::ordered_json& obj,
               const std::set<std::string>& keys) {
  keys_of(file, field, obj, keys);
}

void only_keys(const std::string& file, const std::string& field, const nlohmann::json& obj,
               const std::set<std::string>& keys) {
  keys_of(file, field, obj, keys);
}

bool identifier(const std::string& s) {
  bool ok = !s.empty() && !std::isdigit(static_cast<unsigned char>(s[0])) && s.rfind("gl_", 0) != 0;
  for (char c : s) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
  return ok;
}

std::string text(const std::string& file, const std::string& field, const nlohmann::ordered_json& v) {
  if (!v.is_string()) bad(file, field, v.is_null() ? "is missing" : "must be a string");
  return v.get<std::string>();
}

int integer(const std::string& file, const std::string& field, const nlohmann::ordered_json& v) {
  if (v.is_number_integer()) return v.get<int>();
  if (v.is_string()) {
    const std::string s = v.get<std::string>();
    char* end = nullptr;
    const long n = std::strtol(s.c_str(), &end, 10);
    if (!s.empty() && end && *end == '\0' && n > -100000 && n < 100000) return int(n);
  }
  bad(file, field, v.is_null() ? "is missing" : "must be an integer");
}

}  // namespace bloomref::cli::json_fields
