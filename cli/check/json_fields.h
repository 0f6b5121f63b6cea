// The checks shared by check's JSON inputs (a layout file, a pipeline description): each
// refusal is InputError naming the file and the field (exit 2).
#pragma once

#include <nlohmann/json.hpp>
#include <set>
#include <string>

namespace bloomref::cli::json_fields {

[[noreturn]] void bad(const std::string& file, const std::string& field, const std::string& why);

/// The keys an object may hold; any other is refused (a misspelt key would silently keep a
/// default). `field` "(top level)" for the document itself.
void only_keys(const std::string& file, const std::string& field, const nlohmann::ordered_json& obj,
               const std::set<std::string>& keys);
void only_keys(const std::string& file, const std::string& field, const nlohmann::json& obj,
               const std::set<std::string>& keys);

/// A GLSL identifier a shader can declare: letters, digits and _, not a digit first, not gl_.
bool identifier(const std::string& s);

/// A string value, or an integer given as a number or as a string of one ("{k-1}" expanded).
std::string text(const std::string& file, const std::string& field, const nlohmann::ordered_json& v);
int integer(const std::string& file, const std::string& field, const nlohmann::ordered_json& v);

}  // namespace bloomref::cli::json_fields
