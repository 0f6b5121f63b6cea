#include "presets.h"

#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bloomref/error.h"
#include "options.h"

namespace bloomref::cli {
namespace {

struct Builtin {
  const char* name;
  const char* text;
};

// data/presets/*.json, written into presets_data.inc by cli/CMakeLists.txt.
constexpr Builtin kBuiltin[] = {
#include "presets_data.inc"
};

nlohmann::json parse_preset(const std::string& what, const std::string& text) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw ParamError("preset " + what + " is not valid JSON: " + e.what());
  }
}

nlohmann::json load_preset(const std::string& name_or_file, std::string& what) {
  for (const Builtin& b : kBuiltin)
    if (name_or_file == b.name) {
      what = "'" + name_or_file + "'";
      return parse_preset(what, b.text);
    }
  const bool file = name_or_file.size() > 5 &&
                    name_or_file.compare(name_or_file.size() - 5, 5, ".json") == 0;
  if (!file) {
    std::string known;
    for (const Builtin& b : kBuiltin) known += (known.empty() ? "" : ", ") + std::string(b.name);
    throw ParamError("--preset '" + name_or_file + "' is not one of: " + known +
                     " (or a .json file of the same form)");
  }
  what = name_or_file;
  std::ifstream in(name_or_file, std::ios::binary);
  if (!in) throw InputError(name_or_file, "cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_preset(what, text.str());
}

std::string text_of(const nlohmann::json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number() || v.is_boolean()) return v.dump();
  throw ParamError("is not a string, number or boolean");
}

template <class T>
T number_of(const nlohmann::json& v) {
  if (!v.is_number()) throw ParamError("is not a number");
  return v.get<T>();
}

template <class T>
std::vector<T> numbers_of(const nlohmann::json& v) {
  if (!v.is_array()) throw ParamError("is not an array of numbers");
  std::vector<T> out;
  for (const nlohmann::json& e : v) out.push_back(number_of<T>(e));
  return out;
}

// Each key a preset may set: the CLI option of the same name, and what setting it does.
using Setter = std::function<void(PipelineOptions&, const nlohmann::json&)>;
const std::map<std::string, Setter>& setters() {
  static const std::map<std::string, Setter> s = {
      {"method", [](PipelineOptions& o, const nlohmann::json& v) { o.method = text_of(v); }},
      {"kernel", [](PipelineOptions& o, const nlohmann::json& v) { o.kernel = text_of(v); }},
      {"storage", [](PipelineOptions& o, const nlohmann::json& v) { o.storage = text_of(v); }},
      {"composite", [](PipelineOptions& o, const nlohmann::json& v) { o.composite = text_of(v); }},
      {"composite-mode",
       [](PipelineOptions& o, const nlohmann::json& v) { o.composite_mode = text_of(v); }},
      {"first-axis", [](PipelineOptions& o, const nlohmann::json& v) { o.first_axis = text_of(v); }},
      {"luma", [](PipelineOptions& o, const nlohmann::json& v) { o.luma = text_of(v); }},
      {"luma-space", [](PipelineOptions& o, const nlohmann::json& v) { o.luma_space = text_of(v); }},
      {"prefilter", [](PipelineOptions& o, const nlohmann::json& v) { o.prefilter = text_of(v); }},
      {"karis-form", [](PipelineOptions& o, const nlohmann::json& v) { o.karis_form = text_of(v); }},
      {"texel-step", [](PipelineOptions& o, const nlohmann::json& v) { o.texel_step = text_of(v); }},
      {"bloom-upscale",
       [](PipelineOptions& o, const nlohmann::json& v) { o.bloom_upscale = text_of(v); }},
      {"chain-storage",
       [](PipelineOptions& o, const nlohmann::json& v) { o.chain_storage = text_of(v); }},
      {"level-combine",
       [](PipelineOptions& o, const nlohmann::json& v) { o.level_combine = text_of(v); }},
      {"level-weights",
       [](PipelineOptions& o, const nlohmann::json& v) { o.level_weights = text_of(v); }},
      {"first-level-height",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.first_level_height = number_of<int>(v);
       }},
      {"knee", [](PipelineOptions& o, const nlohmann::json& v) { o.params.knee = number_of<float>(v); }},
      {"knee-form", [](PipelineOptions& o, const nlohmann::json& v) { o.knee_form = text_of(v); }},
      {"clamp-max",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.clamp_max = number_of<float>(v); }},
      {"first-downsample",
       [](PipelineOptions& o, const nlohmann::json& v) { o.first_downsample = text_of(v); }},
      {"downsample", [](PipelineOptions& o, const nlohmann::json& v) { o.downsample = text_of(v); }},
      {"upsample", [](PipelineOptions& o, const nlohmann::json& v) { o.upsample = text_of(v); }},
      {"level-count",
       [](PipelineOptions& o, const nlohmann::json& v) { o.level_count = text_of(v); }},
      {"level-weight",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.level_weight = number_of<float>(v);
       }},
      {"smooth-width",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.smooth_width = number_of<float>(v);
       }},
      {"level-kernels",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.level_kernels = numbers_of<int>(v); }},
      {"level-sigmas",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.level_sigmas = numbers_of<float>(v); }},
      {"level-normalise",
       [](PipelineOptions& o, const nlohmann::json& v) {
         if (!v.is_boolean()) throw ParamError("is not true or false");
         o.params.level_normalise = v.get<bool>();
       }},
      {"level-factors",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.level_factors = numbers_of<float>(v);
       }},
      {"level-radius",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.level_radius = number_of<float>(v);
       }},
      {"level-strength",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.level_strength = number_of<float>(v);
       }},
      {"low-frequency-boost",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.low_frequency_boost = number_of<float>(v);
       }},
      {"low-frequency-boost-curvature",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.low_frequency_boost_curvature = number_of<float>(v);
       }},
      {"high-pass-frequency",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.high_pass_frequency = number_of<float>(v);
       }},
      {"threshold",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.threshold = number_of<float>(v); }},
      {"exposure",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.exposure = number_of<float>(v); }},
      {"gamma", [](PipelineOptions& o, const nlohmann::json& v) { o.params.gamma = number_of<float>(v); }},
      {"strength",
       [](PipelineOptions& o, const nlohmann::json& v) { o.params.strength = number_of<float>(v); }},
      {"upsample-radius",
       [](PipelineOptions& o, const nlohmann::json& v) {
         o.params.upsample_radius = number_of<float>(v);
       }},
      {"passes", [](PipelineOptions& o, const nlohmann::json& v) { o.params.passes = number_of<int>(v); }},
      {"levels", [](PipelineOptions& o, const nlohmann::json& v) { o.params.levels = number_of<int>(v); }},
      {"karis",
       [](PipelineOptions& o, const nlohmann::json& v) {
         if (!v.is_boolean()) throw ParamError("is not true or false");
         o.params.karis = v.get<bool>();
       }},
  };
  return s;
}

}  // namespace

std::vector<PresetInfo> builtin_presets() {
  std::vector<PresetInfo> out;
  for (const Builtin& b : kBuiltin) {
    const nlohmann::json j = parse_preset(b.name, b.text);
    out.push_back({b.name, j.value("title", ""), j.value("source", "")});
  }
  return out;
}

void apply_preset(const std::string& name_or_file, PipelineOptions& o,
                  const std::function<bool(const std::string&)>& given) {
  std::string what;
  const nlohmann::json j = load_preset(name_or_file, what);
  if (!j.is_object() || !j.contains("params") || !j["params"].is_object())
    throw ParamError("preset " + what + " has no \"params\" object");
  for (const auto& [key, value] : j["params"].items()) {
    const auto it = setters().find(key);
    if (it == setters().end()) throw ParamError("preset " + what + ": unknown key '" + key + "'");
    if (given && given(key)) continue;
    try {
      it->second(o, value);
    } catch (const ParamError& e) {
      throw ParamError("preset " + what + ": '" + key + "' " + e.what());
    }
  }
  o.preset = name_or_file;
}

}  // namespace bloomref::cli
