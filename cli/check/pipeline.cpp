#include "check/pipeline.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "bloomref/error.h"
#include "check/json_fields.h"

using nlohmann::ordered_json;

namespace bloomref::cli {
namespace {

namespace fs = std::filesystem;

// The strings of `v` with "{name}", "{name-N}" and "{name+N}" replaced by value, value - N,
// value + N.
ordered_json substituted(const ordered_json& v, const std::string& name, int value) {
  if (v.is_string()) {
    const std::regex ref("\\{" + name + "(?:([+-])([0-9]+))?\\}");
    const std::string s = v.get<std::string>();
    std::string out;
    auto last = s.cbegin();
    for (std::sregex_iterator it(s.begin(), s.end(), ref), end; it != end; ++it) {
      const std::smatch& m = *it;
      out.append(last, m[0].first);
      int n = value;
      if (m[1].matched) n += (m[1] == "+" ? 1 : -1) * std::stoi(m[2].str());
      out += std::to_string(n);
      last = m[0].second;
    }
    out.append(last, s.cend());
    return out;
  }
  if (v.is_array() || v.is_object()) {
    ordered_json out = v;
    for (auto it = out.begin(); it != out.end(); ++it) *it = substituted(*it, name, value);
    return out;
  }
  return v;
}

// The entries of a list, with {"for": NAME, "from": A, "to": B, KEY: [...]} blocks expanded in
// order (counting down when B < A).
std::vector<ordered_json> expanded(const std::string& file, const std::string& field,
                                   const ordered_json& list, const std::string& key) {
  if (!list.is_array()) json_fields::bad(file, field, "must be a list");
  std::vector<ordered_json> out;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const ordered_json& e = list[i];
    const std::string at = field + "[" + std::to_string(i) + "]";
    if (!e.is_object() || !e.contains("for")) {
      out.push_back(e);
      continue;
    }
    json_fields::only_keys(file, at, e, {"for", "from", "to", key});
    const std::string name = json_fields::text(file, at + ".for", e.at("for"));
    if (!json_fields::identifier(name)) json_fields::bad(file, at + ".for", "is not a name");
    const int from = json_fields::integer(file, at + ".from", e.value("from", ordered_json()));
    const int to = json_fields::integer(file, at + ".to", e.value("to", ordered_json()));
    if (!e.contains(key)) json_fields::bad(file, at + "." + key, "is missing");
    const int step = to >= from ? 1 : -1;
    for (int k = from;; k += step) {
      for (const ordered_json& inner : expanded(file, at + "." + key, e.at(key), key))
        out.push_back(substituted(inner, name, k));
      if (k == to) break;
    }
  }
  return out;
}

gpu::DescribedTexture texture(const std::string& file, const std::string& at, const ordered_json& t,
                              const std::set<std::string>& before) {
  using json_fields::bad;
  json_fields::only_keys(file, at, t, {"name", "holds", "size", "format", "filter", "wrap"});
  gpu::DescribedTexture out;
  out.name = json_fields::text(file, at + ".name", t.value("name", ordered_json()));
  if (before.count(out.name)) bad(file, at + ".name", "'" + out.name + "' is declared twice");
  const std::string holds = t.contains("holds") ? json_fields::text(file, at + ".holds", t.at("holds")) : "clear";
  if (holds == "scene") out.content = gpu::DescribedTexture::scene;
  else if (holds == "bright") out.content = gpu::DescribedTexture::bright;
  else if (holds != "clear") bad(file, at + ".holds", "'" + holds + "' is not scene, bright or clear");
  if (t.contains("size")) {
    const ordered_json& s = t.at("size");
    const std::string sat = at + ".size";
    json_fields::only_keys(file, sat, s, {"of", "scale", "halvings", "height", "round", "exact"});
    if (s.contains("exact")) {
      const ordered_json& e = s.at("exact");
      if (s.size() != 1 || !e.is_array() || e.size() != 2 || !e[0].is_number_integer() ||
          !e[1].is_number_integer() || e[0].get<int>() < 1 || e[1].get<int>() < 1 ||
          e[0].get<int>() > 65536 || e[1].get<int>() > 65536)
        bad(file, sat + ".exact", "must be [width, height], integers in [1, 65536], alone");
      out.size.exact_width = e[0].get<int>();
      out.size.exact_height = e[1].get<int>();
    }
    out.size.of = s.contains("of") ? json_fields::text(file, sat + ".of", s.at("of")) : "scene";
    if (out.size.of != "scene" && !before.count(out.size.of))
      bad(file, sat + ".of", "'" + out.size.of + "' is not a texture declared before this one");
    const std::string r = s.contains("round") ? json_fields::text(file, sat + ".round", s.at("round")) : "floor";
    if (r == "round") out.size.rounding = gpu::SizeRule::round;
    else if (r == "ceil") out.size.rounding = gpu::SizeRule::ceil;
    else if (r != "floor") bad(file, sat + ".round", "'" + r + "' is not floor, round or ceil");
    if (int(s.contains("scale")) + int(s.contains("halvings")) + int(s.contains("height")) > 1)
      bad(file, sat, "give one of scale, halvings and height");
    if (s.contains("height")) {
      out.size.height = json_fields::integer(file, sat + ".height", s.at("height"));
      if (out.size.height < 1 || out.size.height > 16384)
        bad(file, sat + ".height", "must be in [1, 16384]");
    }
    if (s.contains("scale")) {
      if (!s.at("scale").is_number() || !(s.at("scale").get<double>() > 0))
        bad(file, sat + ".scale", "must be a number > 0");
      out.size.scale = s.at("scale").get<double>();
    }
    if (s.contains("halvings")) {
      out.size.halvings = json_fields::integer(file, sat + ".halvings", s.at("halvings"));
      if (out.size.halvings < 0 || out.size.halvings > 16)
        bad(file, sat + ".halvings", "must be in [0, 16]");
    }
  }
  try {
    if (t.contains("format"))
      out.format = gpu::parse_target_format(json_fields::text(file, at + ".format", t.at("format")));
    if (t.contains("filter"))
      out.filter = gpu::parse_texture_filter(json_fields::text(file, at + ".filter", t.at("filter")));
    if (t.contains("wrap"))
      out.wrap = gpu::parse_texture_wrap(json_fields::text(file, at + ".wrap", t.at("wrap")));
  } catch (const ParamError& e) {
    bad(file, at, e.what());
  }
  return out;
}

gpu::DescribedUniform uniform(const std::string& file, const std::string& at, const ordered_json& v,
                              const std::set<std::string>& textures) {
  using json_fields::bad;
  gpu::DescribedUniform u;
  auto named_texture = [&](const std::string& key) {
    const std::string t = json_fields::text(file, at + "." + key, v.at(key));
    if (!textures.count(t)) bad(file, at + "." + key, "'" + t + "' is not a declared texture");
    return t;
  };
  if (v.is_boolean()) {
    u.kind = gpu::DescribedUniform::flag;
    u.integer_value = v.get<bool>() ? 1 : 0;
  } else if (v.is_number()) {
    u.values = {v.get<float>()};
  } else if (v.is_array()) {
    if (v.size() < 2 || v.size() > 4) bad(file, at, "a vector has 2 to 4 numbers");
    for (const auto& x : v) {
      if (!x.is_number()) bad(file, at, "a vector's entries must be numbers");
      u.values.push_back(x.get<float>());
    }
  } else if (v.is_object() && v.contains("int")) {
    json_fields::only_keys(file, at, v, {"int"});
    u.kind = gpu::DescribedUniform::integer;
    u.integer_value = json_fields::integer(file, at + ".int", v.at("int"));
  } else if (v.is_object() && v.contains("size_of")) {
    json_fields::only_keys(file, at, v, {"size_of"});
    u.kind = gpu::DescribedUniform::size;
    u.texture = named_texture("size_of");
  } else if (v.is_object() && v.contains("texel_of")) {
    json_fields::only_keys(file, at, v, {"texel_of"});
    u.kind = gpu::DescribedUniform::texel;
    u.texture = named_texture("texel_of");
  } else if (v.is_object() && (v.contains("width_of") || v.contains("height_of"))) {
    const char* key = v.contains("width_of") ? "width_of" : "height_of";
    json_fields::only_keys(file, at, v, {key});
    u.kind = v.contains("width_of") ? gpu::DescribedUniform::width : gpu::DescribedUniform::height;
    u.texture = named_texture(key);
  } else if (v.is_object() && v.contains("halved")) {
    json_fields::only_keys(file, at, v, {"halved", "times"});
    u.kind = gpu::DescribedUniform::halved;
    u.texture = named_texture("halved");
    u.times = json_fields::integer(file, at + ".times", v.value("times", ordered_json(0)));
  } else {
    bad(file, at,
        "is not a uniform value: a number, a list of numbers, true/false, {\"int\": N}, "
        "{\"size_of\": TEXTURE}, {\"texel_of\": TEXTURE}, {\"width_of\": TEXTURE}, "
        "{\"height_of\": TEXTURE} or {\"halved\": TEXTURE, \"times\": N}");
  }
  return u;
}

gpu::DescribedPass pass(const std::string& file, const std::string& at, const ordered_json& p,
                        const gpu::PipelineDescription& d, const std::set<std::string>& textures) {
  using json_fields::bad;
  json_fields::only_keys(file, at, p, {"program", "target", "inputs", "images", "dispatch",
                                       "uniforms", "blend", "clear", "stage"});
  gpu::DescribedPass out;
  out.program = json_fields::text(file, at + ".program", p.value("program", ordered_json()));
  if (!d.programs.count(out.program))
    bad(file, at + ".program", "'" + out.program + "' is not a declared program");
  const bool compute = !d.programs.at(out.program).compute.empty();
  if (compute) {
    out.clear = false;  // a compute pass writes what it writes; "clear": true clears first
    if (p.contains("blend")) bad(file, at + ".blend", "a compute pass blends in its shader, if at all");
  } else {
    for (const char* key : {"images", "dispatch"})
      if (p.contains(key))
        bad(file, at + "." + key, std::string("applies to a compute program's pass; '") +
                                      out.program + "' is a fragment program");
  }
  if (p.contains("images")) {
    const ordered_json& im = p.at("images");
    if (!im.is_object()) bad(file, at + ".images", "must be an object: storage image -> texture");
    for (const auto& [name, tex] : im.items()) {
      const std::string t = json_fields::text(file, at + ".images." + name, tex);
      const bool number = !name.empty() && name.find_first_not_of("0123456789") == std::string::npos;
      if (!number && !json_fields::identifier(name))
        bad(file, at + ".images." + name, "is neither a GLSL name nor a binding number");
      if (!textures.count(t)) bad(file, at + ".images." + name, "'" + t + "' is not a declared texture");
      out.images.emplace_back(name, t);
    }
  }
  if (p.contains("dispatch")) {
    const ordered_json& g = p.at("dispatch");
    if (g.is_array() && g.size() == 2 && g[0].is_number_integer() && g[1].is_number_integer() &&
        g[0].get<int>() > 0 && g[1].get<int>() > 0) {
      out.groups_x = g[0].get<int>();
      out.groups_y = g[1].get<int>();
    } else if (g.is_object()) {
      json_fields::only_keys(file, at + ".dispatch", g, {"over"});
      out.dispatch_over = json_fields::text(file, at + ".dispatch.over", g.value("over", ordered_json()));
      if (!textures.count(out.dispatch_over))
        bad(file, at + ".dispatch.over", "'" + out.dispatch_over + "' is not a declared texture");
    } else {
      bad(file, at + ".dispatch", "must be [groups x, groups y] (positive) or {\"over\": TEXTURE}");
    }
  }
  out.target = json_fields::text(file, at + ".target", p.value("target", ordered_json()));
  if (!textures.count(out.target))
    bad(file, at + ".target", "'" + out.target + "' is not a declared texture");
  if (p.contains("inputs")) {
    const ordered_json& in = p.at("inputs");
    if (!in.is_object()) bad(file, at + ".inputs", "must be an object: sampler -> texture");
    for (const auto& [sampler, tex] : in.items()) {
      const std::string t = json_fields::text(file, at + ".inputs." + sampler, tex);
      if (!json_fields::identifier(sampler)) bad(file, at + ".inputs." + sampler, "is not a GLSL name");
      if (!textures.count(t)) bad(file, at + ".inputs." + sampler, "'" + t + "' is not a declared texture");
      if (t == out.target) bad(file, at + ".inputs." + sampler, "reads the texture the pass draws into");
      out.inputs.emplace_back(sampler, t);
    }
  }
  if (p.contains("uniforms")) {
    const ordered_json& us = p.at("uniforms");
    if (!us.is_object()) bad(file, at + ".uniforms", "must be an object: name -> value");
    for (const auto& [name, v] : us.items()) {
      if (!json_fields::identifier(name)) bad(file, at + ".uniforms." + name, "is not a GLSL name");
      out.uniforms[name] = uniform(file, at + ".uniforms." + name, v, textures);
    }
  }
  if (p.contains("blend")) {
    const ordered_json& b = p.at("blend");
    json_fields::only_keys(file, at + ".blend", b, {"src", "dst", "constant"});
    out.blend.enabled = true;
    out.blend.src = json_fields::text(file, at + ".blend.src", b.value("src", ordered_json()));
    out.blend.dst = json_fields::text(file, at + ".blend.dst", b.value("dst", ordered_json()));
    try {
      gpu::blend_factor(out.blend.src);
      gpu::blend_factor(out.blend.dst);
    } catch (const ParamError& e) {
      bad(file, at + ".blend", e.what());
    }
    if (b.contains("constant")) {
      if (!b.at("constant").is_number()) bad(file, at + ".blend.constant", "must be a number");
      out.blend.constant = b.at("constant").get<float>();
    }
  }
  if (p.contains("clear")) {
    if (!p.at("clear").is_boolean()) bad(file, at + ".clear", "must be true or false");
    out.clear = p.at("clear").get<bool>();
  }
  if (p.contains("stage")) out.stage = json_fields::text(file, at + ".stage", p.at("stage"));
  return out;
}

}  // namespace

gpu::PipelineDescription read_pipeline(const std::string& path) {
  using json_fields::bad;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the pipeline description");
  std::stringstream text;
  text << in.rdbuf();
  ordered_json j;
  try {
    j = ordered_json::parse(text.str());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, std::string("is not valid JSON: ") + e.what());
  }
  json_fields::only_keys(path, "(top level)", j, {"pipeline", "title", "source", "programs",
                                                  "textures", "passes"});
  if (!j.contains("pipeline") || j.at("pipeline") != 1)
    bad(path, "pipeline", "must be 1 (the version of the description format)");
  gpu::PipelineDescription d;
  d.file = path;
  const fs::path folder = fs::path(path).parent_path();
  if (!j.contains("programs") || !j.at("programs").is_object() || j.at("programs").empty())
    bad(path, "programs", "must be an object of at least one program");
  for (const auto& [name, prog] : j.at("programs").items()) {
    const std::string at = "programs." + name;
    json_fields::only_keys(path, at, prog, {"fragment", "vertex", "compute", "entry"});
    gpu::DescribedProgram p;
    if (prog.contains("compute")) {
      if (prog.contains("fragment") || prog.contains("vertex"))
        bad(path, at, "has a compute shader and a fragment or vertex shader: one or the other");
      p.compute = (folder / json_fields::text(path, at + ".compute", prog.at("compute"))).string();
      if (prog.contains("entry")) p.entry = json_fields::text(path, at + ".entry", prog.at("entry"));
      if (!json_fields::identifier(p.entry)) bad(path, at + ".entry", "is not a function name");
    } else {
      if (prog.contains("entry")) bad(path, at + ".entry", "names a compute shader's entry point");
      p.fragment = (folder / json_fields::text(path, at + ".fragment", prog.value("fragment", ordered_json()))).string();
      if (prog.contains("vertex"))
        p.vertex = (folder / json_fields::text(path, at + ".vertex", prog.at("vertex"))).string();
    }
    d.programs[name] = p;
  }
  std::set<std::string> textures;
  if (!j.contains("textures")) bad(path, "textures", "is missing");
  const std::vector<ordered_json> ts = expanded(path, "textures", j.at("textures"), "textures");
  for (std::size_t i = 0; i < ts.size(); ++i) {
    d.textures.push_back(texture(path, "textures[" + std::to_string(i) + "]", ts[i], textures));
    textures.insert(d.textures.back().name);
  }
  if (!j.contains("passes")) bad(path, "passes", "is missing");
  const std::vector<ordered_json> ps = expanded(path, "passes", j.at("passes"), "passes");
  if (ps.empty()) bad(path, "passes", "has no pass");
  std::set<std::string> stages;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const std::string at = "passes[" + std::to_string(i) + "]";
    d.passes.push_back(pass(path, at, ps[i], d, textures));
    const std::string& st = d.passes.back().stage;
    if (!st.empty() && !stages.insert(st).second)
      bad(path, at + ".stage", "'" + st + "' is read back by two passes");
  }
  if (stages.empty()) bad(path, "passes", "no pass names a stage: nothing would be judged");
  return d;
}

namespace {

ordered_json uniform_json(const gpu::DescribedUniform& u) {
  using U = gpu::DescribedUniform;
  switch (u.kind) {
    case U::number: return u.values.size() == 1 ? ordered_json(u.values[0]) : ordered_json(u.values);
    case U::integer: return {{"int", u.integer_value}};
    case U::flag: return ordered_json(u.integer_value != 0);
    case U::size: return {{"size_of", u.texture}};
    case U::texel: return {{"texel_of", u.texture}};
    case U::width: return {{"width_of", u.texture}};
    case U::height: return {{"height_of", u.texture}};
    case U::halved: return {{"halved", u.texture}, {"times", u.times}};
  }
  return nullptr;
}

std::string bare_name(const std::string& fragment) {  // "bloomref's bevy_finish.frag" -> file name
  return fs::path(fragment.substr(fragment.rfind(' ') == std::string::npos ? 0
                                                                          : fragment.rfind(' ') + 1))
      .filename()
      .string();
}

}  // namespace

std::vector<std::pair<std::string, std::string>> pipeline_files(
    const gpu::PipelineDescription& d, const std::string& path, const std::string& title,
    const std::string& source) {
  const std::string folder = fs::path(path).stem().string();
  std::vector<std::pair<std::string, std::string>> files;
  ordered_json j = {{"pipeline", 1}, {"title", title}, {"source", source}};
  ordered_json programs = ordered_json::object();
  for (const auto& [name, prog] : d.programs) {
    if (prog.fragment_text.empty() || !prog.compute.empty() || !prog.vertex.empty())
      throw ParamError("program '" + name + "' is not a built-in fragment program: not written");
    const std::string file = folder + "/" + bare_name(prog.fragment);
    programs[name] = {{"fragment", file}};
    files.emplace_back((fs::path(path).parent_path() / file).string(), prog.fragment_text);
  }
  j["programs"] = programs;
  ordered_json textures = ordered_json::array();
  for (const gpu::DescribedTexture& t : d.textures) {
    ordered_json o = {{"name", t.name}};
    if (t.content != gpu::DescribedTexture::clear)
      o["holds"] = t.content == gpu::DescribedTexture::scene ? "scene" : "bright";
    if (t.size.exact_width > 0) {
      o["size"] = {{"exact", {t.size.exact_width, t.size.exact_height}}};
    } else if (t.size.of != "scene" || t.size.halvings || t.size.height || t.size.scale != 1.0) {
      ordered_json s = {{"of", t.size.of}};
      if (t.size.halvings) s["halvings"] = t.size.halvings;
      if (t.size.height) s["height"] = t.size.height;
      if (t.size.scale != 1.0) s["scale"] = t.size.scale;
      s["round"] = t.size.rounding == gpu::SizeRule::floor   ? "floor"
                   : t.size.rounding == gpu::SizeRule::round ? "round"
                                                             : "ceil";
      o["size"] = s;
    }
    o["format"] = gpu::to_string(t.format);
    o["filter"] = gpu::to_string(t.filter);
    o["wrap"] = gpu::to_string(t.wrap);
    textures.push_back(o);
  }
  j["textures"] = textures;
  ordered_json passes = ordered_json::array();
  for (const gpu::DescribedPass& p : d.passes) {
    ordered_json o = {{"program", p.program}, {"target", p.target}};
    if (!p.inputs.empty()) {
      ordered_json in = ordered_json::object();
      for (const auto& [sampler, texture] : p.inputs) in[sampler] = texture;
      o["inputs"] = in;
    }
    if (!p.uniforms.empty()) {
      ordered_json us = ordered_json::object();
      for (const auto& [name, u] : p.uniforms) us[name] = uniform_json(u);
      o["uniforms"] = us;
    }
    if (p.blend.enabled)
      o["blend"] = {{"src", p.blend.src}, {"dst", p.blend.dst}, {"constant", p.blend.constant}};
    if (!p.clear) o["clear"] = false;
    if (!p.stage.empty()) o["stage"] = p.stage;
    passes.push_back(o);
  }
  j["passes"] = passes;
  files.insert(files.begin(), {path, j.dump(1) + "\n"});
  return files;
}

}  // namespace bloomref::cli
