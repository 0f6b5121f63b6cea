#include "check/manifest.h"

#include <fnmatch.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "bloomref/error.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace bloomref::cli {
namespace {

json read_json(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return json::parse(ss.str());
  } catch (const json::exception& e) {  // parse_error, and out_of_range (a number like 1e999)
    throw InputError(path, std::string("is not valid JSON: ") + e.what());
  }
}

// A field's problem, named by its path in the file ("items[2].stages.blur.3").
[[noreturn]] void bad(const std::string& file, const std::string& field, const std::string& why) {
  throw InputError(file, field + ": " + why);
}

std::string get_string(const std::string& file, const json& obj, const std::string& field,
                       const std::string& key) {
  const json& v = obj.at(key);
  if (!v.is_string()) bad(file, field + "." + key, "must be a string");
  return v.get<std::string>();
}

void check_version(const std::string& file, const json& j) {
  if (!j.is_object()) bad(file, "(top level)", "must be a JSON object");
  if (!j.contains("version")) bad(file, "version", "missing (this bloomref reads version 1)");
  if (j["version"] != 1) bad(file, "version", "is " + j["version"].dump() + "; this bloomref reads version 1");
}

// Applies one manifest parameter to the pipeline options unless given on the command line.
void apply_param(const std::string& file, const std::string& key, const json& v,
                 const std::set<std::string>& given, PipelineOptions& po) {
  std::string option = "--" + key;
  for (char& c : option)
    if (c == '_') c = '-';
  // The command line wins. A key that names no option is refused below.
  if (given.count(option)) return;
  const std::string field = "params." + key;
  auto num = [&]() {
    if (!v.is_number()) bad(file, field, "must be a number");
    return v.get<double>();
  };
  auto integer = [&]() {
    if (!v.is_number_integer()) bad(file, field, "must be an integer");
    return v.get<int>();
  };
  auto str = [&]() {
    if (!v.is_string()) bad(file, field, "must be a string");
    return v.get<std::string>();
  };
  BloomParams& p = po.params;
  if (key == "method") po.method = str();
  else if (key == "threshold") p.threshold = static_cast<float>(num());
  else if (key == "exposure") p.exposure = static_cast<float>(num());
  else if (key == "gamma") p.gamma = static_cast<float>(num());
  else if (key == "strength") p.strength = static_cast<float>(num());
  else if (key == "passes") p.passes = integer();
  else if (key == "kernel") po.kernel = str();
  else if (key == "storage") po.storage = str();
  else if (key == "nonfinite") po.nonfinite = str();
  else if (key == "levels") p.levels = integer();
  else if (key == "karis") {
    if (!v.is_boolean()) bad(file, field, "must be true or false");
    p.karis = v.get<bool>();
  } else if (key == "composite") po.composite = str();
  else if (key == "first_axis") po.first_axis = str();
  else if (key == "luma") po.luma = str();
  else if (key == "luma_space") po.luma_space = str();
  else if (key == "threads") p.threads = integer();
  else
    bad(file, field,
        "is not a pipeline parameter (method, threshold, exposure, gamma, strength, passes, "
        "kernel, storage, nonfinite, levels, karis, composite, first_axis, luma, luma_space, "
        "threads)");
}

fs::path resolve_path(const fs::path& base, const std::string& p) {
  const fs::path q(p);
  return q.is_absolute() ? q : (base / q).lexically_normal();
}

// Encoding, origin, channels, format, width, height of an object, over `f`'s values.
void read_image_fields(const std::string& file, const std::string& field, const json& o,
                       StageFile& f) {
  static const std::set<std::string> known{"path", "encoding", "origin", "channels", "format",
                                           "width", "height"};
  for (const auto& [k, v] : o.items())
    if (!known.count(k))
      bad(file, field + "." + k,
          "unknown field (path, encoding, origin, channels, format, width, height)");
  try {
    if (o.contains("encoding")) f.encoding = parse_encoding(get_string(file, o, field, "encoding"));
    if (o.contains("origin")) f.origin = parse_origin(get_string(file, o, field, "origin"));
    if (o.contains("channels")) f.channels = parse_channel_order(get_string(file, o, field, "channels"));
    if (o.contains("format")) f.format = parse_raw_format(get_string(file, o, field, "format"));
  } catch (const ParamError& e) {
    bad(file, field, e.what());
  }
  for (const char* k : {"width", "height"})
    if (o.contains(k)) {
      if (!o[k].is_number_integer() || o[k].get<long long>() < 1 || o[k].get<long long>() > 65536)
        bad(file, field + "." + k, "must be an integer from 1 to 65536");
      (std::string(k) == "width" ? f.width : f.height) = o[k].get<int>();
    }
}

std::map<std::string, std::string> read_aliases(const std::string& file, const std::string& field,
                                                const json& o) {
  std::map<std::string, std::string> out;
  if (!o.is_object()) bad(file, field, "must be an object from your names to stage names");
  for (const auto& [k, v] : o.items()) {
    if (!v.is_string() || !looks_like_stage(v.get<std::string>()))
      bad(file, field + "." + k, "must name a stage (input, bright, blur.N, down.N, up.N, bloom, "
                                 "composite, tonemap, output)");
    out[k] = v.get<std::string>();
  }
  return out;
}

}  // namespace

namespace {

// A manifest's "device": the keys recorded with every result (api, vendor, renderer, driver).
DeviceKeys read_device(const std::string& path, const json& d) {
  if (!d.is_object()) bad(path, "device", "must be an object");
  DeviceKeys keys;
  for (const auto& [k, v] : d.items()) {
    if (!v.is_string()) bad(path, "device." + k, "must be a string");
    if (k == "api") keys.api = v;
    else if (k == "vendor") keys.vendor = v;
    else if (k == "renderer") keys.renderer = v;
    else if (k == "driver") keys.driver = v;
    else bad(path, "device." + k, "unknown key (api, vendor, renderer, driver)");
  }
  return keys;
}

}  // namespace

std::string item_id_problem(const std::string& id) {
  if (id.empty()) return "is empty";
  if (id.size() > 200) return "is longer than 200 bytes";
  if (id[0] == '.') return "starts with '.'";
  for (char c : id) {
    if (c == '/' || c == '\\') return "holds a '/' or '\\'";
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) return "holds a control character";
  }
  return "";
}

std::string folder_item_id(const std::string& dir) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (ec) p = fs::path(dir).lexically_normal();
  std::string id = p.filename().string();
  if (id.empty() || id == "." || id == "..") id = "stages";
  for (char& c : id)
    if (c == '/' || c == '\\' || static_cast<unsigned char>(c) < 0x20 || c == 0x7F) c = '_';
  if (id[0] == '.') id[0] = '_';
  if (id.size() > 200) id.resize(200);
  return id;
}

Manifest read_manifest(const std::string& path, const std::set<std::string>& given,
                       PipelineOptions& pipeline) {
  const json j = read_json(path);
  check_version(path, j);
  static const std::set<std::string> top{"version", "params", "device", "defaults", "aliases", "items"};
  for (const auto& [k, v] : j.items())
    if (!top.count(k)) bad(path, k, "unknown field (version, params, device, defaults, aliases, items)");
  const fs::path base = fs::path(path).parent_path();
  Manifest m;
  if (j.contains("params")) {
    if (!j["params"].is_object()) bad(path, "params", "must be an object");
    std::set<std::string> keys;
    for (const auto& [k, v] : j["params"].items()) {
      apply_param(path, k, v, given, pipeline);
      std::string option = "--" + k;
      for (char& c : option)
        if (c == '_') c = '-';
      keys.insert(option);
    }
    const OptionGiven line = pipeline.given;
    pipeline.given = [line, keys](const std::string& option) {
      return keys.count(option) > 0 || (line && line(option));
    };
    try {
      pipeline.finish();
    } catch (const ParamError& e) {
      bad(path, "params", e.what());
    }
  } else {
    refuse_ignored_options(pipeline.params, pipeline.given);  // the command line's alone
  }
  if (j.contains("device")) m.device = read_device(path, j["device"]);
  StageFile defaults;
  if (j.contains("defaults")) {
    if (!j["defaults"].is_object()) bad(path, "defaults", "must be an object");
    if (j["defaults"].contains("path")) bad(path, "defaults.path", "a default cannot name a file");
    read_image_fields(path, "defaults", j["defaults"], defaults);
  }
  std::map<std::string, std::string> aliases;
  if (j.contains("aliases")) aliases = read_aliases(path, "aliases", j["aliases"]);
  if (!j.contains("items") || !j["items"].is_array())
    bad(path, "items", "missing, or not an array of {id, scene, stages}");
  std::set<std::string> ids;
  int index = 0;
  for (const json& it : j["items"]) {
    const std::string field = "items[" + std::to_string(index++) + "]";
    if (!it.is_object()) bad(path, field, "must be an object {id, scene, stages}");
    for (const auto& [k, v] : it.items())
      if (k != "id" && k != "scene" && k != "stages" && k != "aliases")
        bad(path, field + "." + k, "unknown field (id, scene, stages, aliases)");
    CheckItem item;
    item.defaults = defaults;
    item.id = it.contains("id") ? get_string(path, it, field, "id") : "item-" + std::to_string(index);
    if (const std::string why = item_id_problem(item.id); !why.empty())
      bad(path, field + ".id", why + " (an id names the item's report folder)");
    if (!ids.insert(item.id).second) bad(path, field + ".id", "'" + item.id + "' is used twice");
    if (!it.contains("scene")) bad(path, field + ".scene", "missing (the scene image's path)");
    item.scene = resolve_path(base, get_string(path, it, field, "scene")).string();
    std::error_code ec;
    if (!fs::is_regular_file(item.scene, ec))
      bad(path, field + ".scene", "no such file: " + item.scene);
    std::map<std::string, std::string> item_aliases = aliases;
    if (it.contains("aliases"))
      for (const auto& [k, v] : read_aliases(path, field + ".aliases", it["aliases"]))
        item_aliases[k] = v;
    item.aliases = item_aliases;
    if (!it.contains("stages")) bad(path, field + ".stages", "missing (a folder, or {stage: file})");
    const json& st = it["stages"];
    if (st.is_string()) {
      item.stages_dir = resolve_path(base, st.get<std::string>()).string();
      if (!fs::is_directory(item.stages_dir, ec))
        bad(path, field + ".stages", "no such folder: " + item.stages_dir);
    } else if (st.is_object()) {
      std::set<std::string> stages;
      for (const auto& [name, v] : st.items()) {
        const std::string sf = field + ".stages." + name;
        StageFile f = defaults;
        const auto alias = item_aliases.find(name);
        f.stage = alias != item_aliases.end() ? alias->second : name;
        if (!looks_like_stage(f.stage))
          bad(path, sf, "'" + name + "' is not a stage name (input, bright, blur.N, down.N, "
                        "up.N, bloom, composite, tonemap, output) and no alias maps it to one");
        if (!stages.insert(f.stage).second) bad(path, sf, "stage '" + f.stage + "' is given twice");
        if (v.is_string()) {
          f.path = v.get<std::string>();
        } else if (v.is_object()) {
          if (!v.contains("path")) bad(path, sf + ".path", "missing");
          f.path = get_string(path, v, sf, "path");
          read_image_fields(path, sf, v, f);
        } else {
          bad(path, sf, "must be a path or {path, encoding, origin, channels, format, width, height}");
        }
        f.path = resolve_path(base, f.path).string();
        if (!fs::is_regular_file(f.path, ec)) bad(path, sf, "no such file: " + f.path);
        item.files.push_back(f);
      }
    } else {
      bad(path, field + ".stages", "must be a folder or an object {stage: file}");
    }
    m.items.push_back(std::move(item));
  }
  if (m.items.empty()) bad(path, "items", "is empty: nothing to check");
  return m;
}

std::vector<Expectation> read_expectations(const std::string& path) {
  const json j = read_json(path);
  check_version(path, j);
  if (!j.contains("expectations") || !j["expectations"].is_array())
    bad(path, "expectations", "missing, or not an array of {item, stage, device, reason}");
  std::vector<Expectation> out;
  int index = 0;
  for (const json& e : j["expectations"]) {
    const std::string field = "expectations[" + std::to_string(index++) + "]";
    if (!e.is_object()) bad(path, field, "must be an object {item, stage, device, reason}");
    Expectation x;
    for (const auto& [k, v] : e.items()) {
      if (!v.is_string()) bad(path, field + "." + k, "must be a string");
      if (k == "item") x.item = v;
      else if (k == "stage") x.stage = v;
      else if (k == "device") x.device = v;
      else if (k == "reason") x.reason = v;
      else bad(path, field + "." + k, "unknown field (item, stage, device, reason)");
    }
    if (x.reason.empty()) bad(path, field + ".reason", "missing: say why the deviation is known");
    out.push_back(x);
  }
  return out;
}

namespace {

parity::ImageGates read_gates(const std::string& file, const std::string& field, const json& g,
                              parity::ImageGates out) {
  if (!g.is_object()) bad(file, field, "must be an object {mean, window, window_size, over_fraction, gain}");
  for (const auto& [k, v] : g.items()) {
    if (!v.is_number() || v.get<double>() < 0) bad(file, field + "." + k, "must be a number >= 0");
    if (k == "mean") out.mean = v;
    else if (k == "window") out.window = v;
    else if (k == "window_size") {
      if (!v.is_number_integer() || v.get<int>() < 1) bad(file, field + "." + k, "must be an integer >= 1");
      out.window_size = v;
    } else if (k == "over_fraction") out.over_fraction = v;
    else if (k == "gain") out.gain = v;
    else bad(file, field + "." + k, "unknown gate (mean, window, window_size, over_fraction, gain)");
  }
  return out;
}

}  // namespace

parity::DeviceProfile read_profile_file(const std::string& path) {
  const json j = read_json(path);
  check_version(path, j);
  parity::DeviceProfile p;
  try {
    p = parity::profile_named(j.contains("base") ? get_string(path, j, "(top level)", "base")
                                                 : std::string("nvidia"));
  } catch (const ParamError& e) {
    bad(path, "base", e.what());
  }
  p.source = "profile file " + path + " (based on " + p.name + ")";
  p.name = fs::path(path).stem().string();
  for (const auto& kv : j.items()) {
    const std::string& k = kv.key();  // the lambdas below read k and v (C++17: no bindings)
    const json& v = kv.value();
    auto boolean = [&]() {
      if (!v.is_boolean()) bad(path, k, "must be true or false");
      return v.get<bool>();
    };
    auto integer = [&](int lo, int hi) {
      if (!v.is_number_integer() || v.get<int>() < lo || v.get<int>() > hi)
        bad(path, k, "must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi));
      return v.get<int>();
    };
    auto number = [&]() {
      if (!v.is_number() || !(v.get<double>() >= 0)) bad(path, k, "must be a number >= 0");
      return v.get<double>();
    };
    if (k == "version" || k == "base") continue;
    if (k == "name") p.name = get_string(path, j, "(top level)", "name");
    else if (k == "source") p.source = get_string(path, j, "(top level)", "source");
    else if (k == "subtexel_bits") p.subtexel_bits = integer(0, 16);
    else if (k == "subtexel_bits_min") p.subtexel_bits_min = integer(0, 16);
    else if (k == "half_nearest_even") p.half_nearest_even = boolean();
    else if (k == "half_toward_zero") p.half_toward_zero = boolean();
    else if (k == "half_overflow_inf") p.half_overflow_inf = boolean();
    else if (k == "half_overflow_saturate") p.half_overflow_saturate = boolean();
    else if (k == "flush_denormals") p.flush_denormals = boolean();
    else if (k == "fma") p.fma = boolean();
    else if (k == "division_ulps") p.division_ulps = number();
    else if (k == "unit_roundoff") p.unit_roundoff = number();
    else if (k == "capture_code_bits") p.capture_code_bits = integer(0, 16);
    else if (k == "gates") p.gates = read_gates(path, "gates", v, p.gates);
    else if (k == "stages") {
      if (!v.is_array()) bad(path, "stages", "must be an array of {pattern, scale, absolute, gates}");
      int i = 0;
      for (const json& o : v) {
        const std::string field = "stages[" + std::to_string(i++) + "]";
        if (!o.is_object() || !o.contains("pattern"))
          bad(path, field, "must be an object with a pattern (e.g. \"blur.*\")");
        parity::StageOverride so;
        for (const auto& [ok, ov] : o.items()) {
          if (ok == "pattern") so.pattern = get_string(path, o, field, "pattern");
          else if (ok == "scale" || ok == "absolute") {
            if (!ov.is_number() || !(ov.get<double>() >= 0))
              bad(path, field + "." + ok, "must be a number >= 0");
            (ok == "scale" ? so.scale : so.absolute) = ov.get<double>();
          } else if (ok == "gates") {
            so.gates = read_gates(path, field + ".gates", ov, p.gates);
            so.has_gates = true;
          } else {
            bad(path, field + "." + ok, "unknown field (pattern, scale, absolute, gates)");
          }
        }
        p.overrides.push_back(so);
      }
    } else {
      bad(path, k, "unknown field (base, name, source, subtexel_bits, subtexel_bits_min, "
                   "half_nearest_even, half_toward_zero, half_overflow_inf, "
                   "half_overflow_saturate, flush_denormals, fma, division_ulps, unit_roundoff, "
                   "capture_code_bits, gates, stages)");
    }
  }
  if (p.half_nearest_even == false && p.half_toward_zero == false)
    bad(path, "half_nearest_even", "one of half_nearest_even and half_toward_zero must be true");
  return p;
}

void apply_expectations(ItemResult& r, std::vector<Expectation>& expectations,
                        const DeviceKeys& device) {
  const std::string keys[] = {device.api, device.vendor, device.renderer, device.driver};
  auto device_matches = [&](const Expectation& e) {
    if (e.device.empty()) return true;
    for (const std::string& k : keys)
      if (!k.empty() && k.find(e.device) != std::string::npos) return true;
    return false;
  };
  r.outcomes.clear();
  bool fail = false, warn = false, clean_so_far = true;
  for (std::size_t i = 0; i < r.parity.isolated.size(); ++i) {
    const parity::StageComparison& s = r.parity.isolated[i];
    parity::Verdict v = s.verdict;
    // End to end counts where every stage before was clean in isolation: then the error was
    // made across stages, and no isolated failure explains it.
    if (v == parity::Verdict::pass && clean_so_far)
      v = std::max(v, r.parity.end_to_end[i].verdict);
    clean_so_far &= s.verdict == parity::Verdict::pass;
    StageOutcome o;
    for (Expectation& e : expectations)
      if (fnmatch(e.item.c_str(), r.id.c_str(), 0) == 0 &&
          fnmatch(e.stage.c_str(), s.stage.c_str(), 0) == 0 && device_matches(e)) {
        e.used = true;
        o.expectation = e;
        break;
      }
    if (o.expectation) {
      o.status = v == parity::Verdict::pass ? "fixed" : "expected-fail";
    } else {
      o.status = v == parity::Verdict::pass ? "pass" : v == parity::Verdict::warn ? "warn" : "fail";
      fail |= v == parity::Verdict::fail;
      warn |= v == parity::Verdict::warn;
    }
    r.outcomes.push_back(o);
  }
  // A verdict that could not see the gain it had to: not a PASS.
  warn |= r.weak();
  r.verdict = r.parity.isolated.empty() ? "NOTHING" : fail ? "FAIL" : warn ? "WARN" : "PASS";
}

void finish_run(CheckRun& run) {
  bool fail = false, warn = false, nothing = run.items.empty(), error = false;
  for (const ItemResult& r : run.items) {
    error |= r.verdict == "ERROR";
    fail |= r.verdict == "FAIL";
    warn |= r.verdict == "WARN";
    nothing |= r.verdict == "NOTHING";
  }
  if (error) {
    run.verdict = "ERROR";
    run.exit_code = 2;
  } else if (fail || (warn && run.warn_as_error)) {
    run.verdict = "FAIL";
    run.exit_code = 1;
  } else if (nothing) {
    run.verdict = "NOTHING";
    run.exit_code = 5;
  } else {
    run.verdict = warn ? "WARN" : "PASS";
    run.exit_code = 0;
  }
}

}  // namespace bloomref::cli
