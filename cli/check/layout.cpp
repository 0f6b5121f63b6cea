#include "check/layout.h"

#include <cctype>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "bloomref/error.h"
#include "check/json_fields.h"

using nlohmann::json;

namespace bloomref::cli {
namespace {

using json_fields::bad;
using json_fields::identifier;
using json_fields::only_keys;

// obj[key], when there, as the name the user's shaders give that role.
void name(const std::string& file, const json& obj, const std::string& field,
          const std::string& key, std::string& out) {
  if (!obj.contains(key)) return;
  const json& v = obj.at(key);
  const std::string where = (field == "(top level)" ? "" : field + ".") + key;
  if (!v.is_string()) bad(file, where, "must be a string (the name in your shaders)");
  const std::string s = v.get<std::string>();
  if (!identifier(s)) bad(file, where, "'" + s + "' is not a GLSL identifier");
  out = s;
}

gpu::LayoutValue value(const std::string& file, const std::string& field, const json& v) {
  gpu::LayoutValue out;
  if (v.is_string()) {
    const std::string s = v.get<std::string>();
    if (s == "texel-size") out.kind = gpu::LayoutValue::texel_size;
    else if (s == "target-size") out.kind = gpu::LayoutValue::target_size;
    else if (s == "texel-x") out.kind = gpu::LayoutValue::texel_x;
    else if (s == "texel-y") out.kind = gpu::LayoutValue::texel_y;
    else
      bad(file, field,
          "'" + s + "' is not a value the host computes (texel-size, target-size, texel-x, texel-y)");
    return out;
  }
  if (v.is_number()) {
    out.values.push_back(v.get<float>());
  } else if (v.is_array() && !v.empty() && v.size() <= 4) {
    for (const json& x : v) {
      if (!x.is_number()) bad(file, field, "must hold numbers only");
      out.values.push_back(x.get<float>());
    }
  } else {
    bad(file, field,
        "must be a number, 1 to 4 numbers, or \"texel-size\", \"target-size\", \"texel-x\", "
        "\"texel-y\"");
  }
  for (float x : out.values)
    if (!std::isfinite(x)) bad(file, field, "must be finite");
  return out;
}

void set_of(const std::string& file, const json& obj, const std::string& field,
            std::vector<std::pair<std::string, gpu::LayoutValue>>& out) {
  if (!obj.contains("set")) return;
  const json& set = obj.at("set");
  const std::string where = field + ".set";
  if (!set.is_object()) bad(file, where, "must be a JSON object of uniform names and values");
  for (const auto& [key, v] : set.items()) {
    if (!identifier(key)) bad(file, where + "." + key, "'" + key + "' is not a GLSL identifier");
    out.emplace_back(key, value(file, where + "." + key, v));
  }
}

}  // namespace

gpu::PresetLayout read_layout(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  json j;
  try {
    j = json::parse(ss.str());
  } catch (const json::exception& e) {
    throw InputError(path, std::string("is not valid JSON: ") + e.what());
  }
  if (!j.is_object()) bad(path, "(top level)", "must be a JSON object");
  if (!j.contains("version")) bad(path, "version", "missing (this bloomref reads version 1)");
  if (j["version"] != 1)
    bad(path, "version", "is " + j["version"].dump() + "; this bloomref reads version 1");
  only_keys(path, "(top level)", j, {"version", "attributes", "varying", "bright", "blur", "final"});
  gpu::PresetLayout l;
  l.file = path;
  if (j.contains("attributes")) {
    const json& a = j["attributes"];
    only_keys(path, "attributes", a, {"position", "texcoords"});
    name(path, a, "attributes", "position", l.position);
    name(path, a, "attributes", "texcoords", l.texcoords);
  }
  name(path, j, "(top level)", "varying", l.varying);
  if (j.contains("bright")) {
    const json& b = j["bright"];
    only_keys(path, "bright", b, {"scene", "threshold", "set"});
    name(path, b, "bright", "scene", l.bright_scene);
    name(path, b, "bright", "threshold", l.threshold);
    set_of(path, b, "bright", l.bright_set);
  }
  if (j.contains("blur")) {
    const json& b = j["blur"];
    only_keys(path, "blur", b, {"image", "horizontal", "direction", "set"});
    name(path, b, "blur", "image", l.blur_image);
    name(path, b, "blur", "horizontal", l.horizontal);
    if (b.contains("direction")) {
      if (b.contains("horizontal"))
        bad(path, "blur.direction", "give either a horizontal flag or a direction, not both");
      const json& d = b["direction"];
      only_keys(path, "blur.direction", d, {"uniform", "horizontal", "vertical"});
      for (const char* k : {"uniform", "horizontal", "vertical"})
        if (!d.contains(k)) bad(path, std::string("blur.direction.") + k, "missing");
      name(path, d, "blur.direction", "uniform", l.direction);
      l.direction_h = value(path, "blur.direction.horizontal", d["horizontal"]);
      l.direction_v = value(path, "blur.direction.vertical", d["vertical"]);
      if (l.direction_h.components() != l.direction_v.components())
        bad(path, "blur.direction", "horizontal and vertical must have as many components each");
    }
    set_of(path, b, "blur", l.blur_set);
  }
  if (j.contains("final")) {
    const json& f = j["final"];
    only_keys(path, "final", f, {"scene", "bloomBlur", "bloom", "exposure", "set"});
    name(path, f, "final", "scene", l.final_scene);
    name(path, f, "final", "bloomBlur", l.final_bloom);
    name(path, f, "final", "bloom", l.bloom);
    name(path, f, "final", "exposure", l.exposure);
    set_of(path, f, "final", l.final_set);
  }
  return l;
}

}  // namespace bloomref::cli
