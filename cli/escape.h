// Text from users (scene and folder names, manifest ids, device keys, messages quoting them) in
// every language bloomref writes: one function per language, used by every writer, so that a
// name is data whatever its bytes (docs/design.md, "Untrusted names").
//
// A byte that is not part of valid UTF-8 is kept, written as the four characters \xHH, in every
// language: the results still say which file it was, and every parser reads them.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace bloomref::escape {

/// Valid UTF-8: each byte outside a well-formed sequence (overlong forms, surrogates and code
/// points past U+10FFFF included) becomes \xHH; the rest is kept as it is.
std::string utf8(std::string_view s);

/// HTML text and attribute values (quoted with ' or "): & < > " ' as references, control
/// characters other than tab and newline as \xHH.
std::string html(std::string_view s);

/// A relative link to a file named by user text: every byte but A-Z a-z 0-9 - . _ ~ / is
/// percent-encoded (so ':' cannot start a scheme), a leading "//" (another host) made "/", then
/// HTML-escaped.
std::string url(std::string_view path);

/// XML 1.0 text and attribute values: & < > " ' as references, tab, newline and carriage return
/// as character references (kept through attribute normalisation), every character XML 1.0
/// forbids (other controls, U+FFFE, U+FFFF) as \xHH.
std::string xml(std::string_view s);

/// One cell of a Markdown table (GitHub-flavoured): on one line (newlines and controls as
/// spaces), | and Markdown's inline markers backslash-escaped, < > & as HTML references.
std::string markdown_cell(std::string_view s);

/// Inline code in Markdown: backticks in `s` are replaced so that the span cannot end early.
std::string markdown_code(std::string_view s);

/// `j` with every string (keys included) made valid UTF-8 as utf8() does.
nlohmann::ordered_json json_valid(const nlohmann::ordered_json& j);

/// JSON text of `j` (indent as nlohmann's dump), every string valid UTF-8 as utf8() makes it.
std::string json_text(const nlohmann::ordered_json& j, int indent = 2);

}  // namespace bloomref::escape
