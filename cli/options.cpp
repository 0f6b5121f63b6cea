#include "options.h"

#include <cmath>
#include <set>

#include "bloomref/error.h"
#include "bloomref/memory_budget.h"
#include "bloomref/scenes.h"
#include "presets.h"

namespace bloomref::cli {

void PipelineOptions::add_to(CLI::App& app) {
  BloomParams& p = params;
  // What the user gave, kept when parsing completes (the app may be gone when finish() runs:
  // Python's check parses, then judges).
  app.parse_complete_callback([this, &app] {
    std::set<std::string> names;
    for (const CLI::Option* o : app.get_options())
      if (o->count() > 0)
        for (const std::string& n : o->get_lnames()) names.insert("--" + n);
    given = [names](const std::string& option) { return names.count(option) > 0; };
  });
  // First: CLI11 runs the callbacks of the options given in the order they are defined here, so
  // the preset sets every value before the options given beside it override theirs.
  std::string names;
  for (const PresetInfo& i : builtin_presets()) names += (names.empty() ? "" : " | ") + i.name;
  app.add_option_function<std::string>(
      "--preset",
      [this](const std::string& name) {
        try {
          apply_preset(name, *this);
        } catch (const Error& e) {
          throw CLI::ValidationError("--preset", e.what());
        }
      },
      names + " | FILE.json: a named parameter set (docs/presets.md); options given beside it "
              "override its values");
  app.add_option("--method", method, "gaussian | mip (the mip chain of Jimenez 2014)")->capture_default_str();
  app.add_option("--threshold", p.threshold, "bright when luminance > threshold")
      ->capture_default_str();
  app.add_option("--exposure", p.exposure, "tone map 1 - exp(-hdr * exposure)")
      ->capture_default_str();
  app.add_option("--gamma", p.gamma, "output pow(x, 1 / gamma)")->capture_default_str();
  app.add_option("--passes", p.passes, "single-direction blur passes")->capture_default_str();
  app.add_option("--kernel", kernel, "discrete9 | linear5")->capture_default_str();
  app.add_option("--strength", p.strength, "composite scene + strength * bloom")
      ->capture_default_str();
  app.add_option("--storage", storage,
                 "f32 | f16 | r11g11b10 | rgba8: how every stage is stored (the mip chain's "
                 "levels too, unless --chain-storage)")
      ->capture_default_str();
  app.add_option("--precision", precision, "f32 (the shaders' order) | f64 (the truth)")
      ->capture_default_str();
  app.add_option("--nonfinite", nonfinite, "zero | clamp | propagate | error")
      ->capture_default_str();
  app.add_option("--subtexel-bits", p.subtexel_bits,
                 "bilinear weight precision: 0 = float weights, 8 = 8-bit fixed point")
      ->capture_default_str();
  app.add_option("--threads", p.threads, "0 = all hardware threads")->capture_default_str();
  app.add_option("--plan", plan, "adaptive | full (same bits)")->capture_default_str();
  app.add_option("--blur", blur,
                 "f32 gaussian blur: fast (tiled, vectorised; vectorised tone map and output) | "
                 "reference (the per-texel loop, the scalar stages), same bits; approx "
                 "(texel-exact taps, FMA: faster, not GL's sampling)")
      ->capture_default_str();
  app.add_option("--levels", p.levels, "mip: downsample levels (fewer when the image ends)")
      ->capture_default_str();
  app.add_flag("--karis", p.karis, "mip: Karis average on the first downsample");
  app.add_option("--composite", composite, "before-tonemap | after-tonemap (after: as the mip-chain tutorial)")
      ->capture_default_str();
  app.add_option("--luma", luma,
                 "the luminance the threshold (and seed 002's per-tap Karis weight) reads: rec709 "
                 "(0.2126, 0.7152, 0.0722: the seeds') | rec601 (0.299, 0.587, 0.114)")
      ->capture_default_str();
  app.add_option("--luma-space", luma_space,
                 "the colour the threshold's luminance is taken of: linear (the seeds') | srgb "
                 "(max(c, 0) by IEC 61966-2-1's curve) | gamma (max(c, 0)^(1 / --gamma))")
      ->capture_default_str();
  app.add_option("--first-axis", first_axis,
                 "gaussian: the first blur pass's axis, horizontal (the seeds') | vertical; the "
                 "passes then alternate")
      ->capture_default_str();
  app.add_option("--composite-mode", composite_mode,
                 "add (image + strength * bloom) | mix (mix(image, bloom, strength))")
      ->capture_default_str();
  app.add_option("--prefilter", prefilter,
                 "mip: per-lookup (the first downsample thresholds each tap) | bright (a bright "
                 "stage, luminance > threshold, before the chain) | none (the chain reads the "
                 "scene) | soft-knee (the first level scaled by Bevy's and Unity's soft "
                 "threshold) | smoothstep (three.js's high pass)")
      ->capture_default_str();
  app.add_option("--karis-form", karis_form,
                 "mip, with --karis: per-tap (1 / (1 + L) per tap, normalised per group) | "
                 "group-srgb (per group on pow(group, 1/2.2), Rec. 601, as LearnOpenGL's PBB) | "
                 "group-linear (per group, Rec. 709 on linear colour, clamped, as Bevy)")
      ->capture_default_str();
  app.add_option("--texel-step", texel_step,
                 "mip: the downsample's texel step from the source texture's size (texture) or "
                 "from the image size halved per level in float (halved-float)")
      ->capture_default_str();
  app.add_option("--upsample-radius", p.upsample_radius,
                 "mip: the upsample tent's tap distance in texture coordinates (0 = one texel)")
      ->capture_default_str();
  app.add_option("--bloom-upscale", bloom_upscale,
                 "mip: the full-resolution bloom from up.1 by the tent | one bilinear lookup")
      ->capture_default_str();
  app.add_option("--first-level-height", p.first_level_height,
                 "mip: the first level's height, its width in proportion (Bevy's "
                 "max_mip_dimension); 0 = half the image")
      ->capture_default_str();
  app.add_option("--knee", p.knee,
                 "mip, --prefilter soft-knee: the knee as a fraction of the threshold, in [0, 1] "
                 "(Bevy's threshold_softness)")
      ->capture_default_str();
  app.add_option("--knee-form", knee_form,
                 "mip, --prefilter soft-knee: the soft threshold's arithmetic, bevy | unity "
                 "(Unity URP's FragPrefilter)")
      ->capture_default_str();
  app.add_option("--clamp-max", p.clamp_max,
                 "mip: the first level clamped to at most this before the soft threshold "
                 "(Unity's clamp); 0 = none")
      ->capture_default_str();
  app.add_option("--first-downsample", first_downsample,
                 "mip: the first level by 13-tap (seed 003) | bilinear (one lookup, Unity's "
                 "prefilter) | box4 (four lookups at +-1 texel)")
      ->capture_default_str();
  app.add_option("--downsample", downsample,
                 "mip: the other levels by 13-tap (seed 003) | gaussian (Unity's 9-tap "
                 "horizontal 2x downsample, then 5 bilinear taps vertical) | separable "
                 "(three.js's Gaussian of --level-kernels, along x then y) | box4 (four lookups "
                 "at +-1 texel)")
      ->capture_default_str();
  app.add_option("--upsample", upsample,
                 "mip: what up.k reads of the level below: tent (3x3) | bilinear (one lookup)")
      ->capture_default_str();
  app.add_option("--level-count", level_count,
                 "mip: fixed (--levels) | unity (URP's floor(log2(max(w, h) / 2)) - 1, at most "
                 "--levels) | threejs (a high pass at round(n / 2), then --levels blurred mips)")
      ->capture_default_str();
  app.add_option("--level-combine", level_combine,
                 "mip: up.k = down.k + C tent (add) | C tent + (1 - C) down.k (mix) | "
                 "down.k + (tent - down.k) C (lerp) | sum (one up.1: the blurred levels times "
                 "--level-factors, three.js's)")
      ->capture_default_str();
  app.add_option("--level-weights", level_weights,
                 "mip: the constants C per level: one | bevy (Bevy's compute_blend_factor, "
                 "intensity = --strength) | constant (--level-weight)")
      ->capture_default_str();
  app.add_option("--smooth-width", p.smooth_width,
                 "mip, --prefilter smoothstep: the smoothstep's width above the threshold "
                 "(three.js's smoothWidth)")
      ->capture_default_str();
  app.add_option("--level-kernels", p.level_kernels,
                 "mip, --downsample separable: each blurred level's kernel radius R, comma "
                 "separated (three.js's kernelSizeArray; sigma R / 3)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--level-sigmas", p.level_sigmas,
                 "mip, --downsample separable: each blurred level's sigma, comma separated "
                 "(default: its radius / 3, three.js's)")
      ->delimiter(',');
  app.add_flag("--level-normalise,!--no-level-normalise", p.level_normalise,
               "mip, --downsample separable: each blurred level's coefficients divided by their "
               "sum (UnrealBloomPass's weightSum; BloomNode's are not)");
  app.add_option("--level-factors", p.level_factors,
                 "mip, --level-combine sum: each blurred level's factor, comma separated "
                 "(three.js's bloomFactors)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--level-radius", p.level_radius,
                 "mip, --level-combine sum: mirrors the factors about 0.6, in [0, 1] (three.js's "
                 "radius)")
      ->capture_default_str();
  app.add_option("--level-strength", p.level_strength,
                 "mip, --level-combine sum: the sum's multiplier (three.js's strength)")
      ->capture_default_str();
  app.add_option("--level-weight", p.level_weight,
                 "mip, --level-weights constant: C at every level, in [0, 1] (Unity's scatter)")
      ->capture_default_str();
  app.add_option("--low-frequency-boost", p.low_frequency_boost,
                 "mip, --level-weights bevy: low_frequency_boost")
      ->capture_default_str();
  app.add_option("--low-frequency-boost-curvature", p.low_frequency_boost_curvature,
                 "mip, --level-weights bevy: low_frequency_boost_curvature, in [0, 1)")
      ->capture_default_str();
  app.add_option("--high-pass-frequency", p.high_pass_frequency,
                 "mip, --level-weights bevy: high_pass_frequency, in (0, 1]")
      ->capture_default_str();
  app.add_option("--chain-storage", chain_storage,
                 "mip: how the levels are stored: f32 | f16 | r11g11b10 | rgba8 (default: --storage)");
  app.add_option("--scene", scene, "built-in scene used when no IN is given")
      ->capture_default_str();
  app.add_option("--size", size, "WxH of the built-in scene (default: the scene's own)");
  app.add_option("--max-memory", max_memory,
                 "refuse (exit 2) an image whose run would need more memory than this, e.g. "
                 "8G (default: 80% of physical memory or the control group's limit)");
}

void PipelineOptions::finish(bool refuse_ignored) {
  params.method = parse_method(method);
  params.kernel = parse_kernel(kernel);
  params.storage = parse_storage(storage);
  params.precision = parse_precision(precision);
  params.nonfinite = parse_nonfinite(nonfinite);
  params.plan = parse_plan_mode(plan);
  params.blur = parse_blur_impl(blur);
  params.composite = parse_composite_order(composite);
  params.composite_mode = parse_composite_mode(composite_mode);
  params.first_axis = parse_first_axis(first_axis);
  params.luma = parse_luma(luma);
  params.luma_space = parse_luma_space(luma_space);
  params.prefilter = parse_prefilter(prefilter);
  params.karis_form = parse_karis_form(karis_form);
  params.texel_step = parse_texel_step(texel_step);
  params.bloom_upscale = parse_bloom_upscale(bloom_upscale);
  params.level_combine = parse_level_combine(level_combine);
  params.level_weights = parse_level_weights(level_weights);
  params.knee_form = parse_knee_form(knee_form);
  params.first_downsample = parse_first_downsample(first_downsample);
  params.downsample = parse_downsample_filter(downsample);
  params.upsample = parse_upsample_filter(upsample);
  params.level_count = parse_level_count(level_count);
  params.chain_storage_set = !chain_storage.empty();
  if (params.chain_storage_set) params.chain_storage = parse_chain_storage(chain_storage);
  validate(params);
  if (refuse_ignored) refuse_ignored_options(params, given);
  if (!max_memory.empty()) parse_byte_size(max_memory, "--max-memory");  // a usage error now
}

void PipelineOptions::scene_size(int& w, int& h) const {
  w = h = 0;
  if (!size.empty()) parse_size(size, w, h);
}

LoadedImage PipelineOptions::load_input(const std::string& input, std::string& source) const {
  LoadedImage in;
  set_io_threads(params.threads);  // the EXR reader and writers use as many as the pipeline
  if (!input.empty()) {
    SizeLimits limits;
    limits.accept = [this](const std::string& path, int w, int h) { check_memory(path, w, h, true); };
    in = load_image(input, limits);
    source = input;
    return in;
  }
  int w = 0, h = 0;
  scene_size(w, h);
  if (w == 0 || h == 0)
    for (const SceneInfo& s : scene_list())
      if (s.name == scene) {
        w = w ? w : s.width;
        h = h ? h : s.height;
      }
  check_memory("--scene " + scene + " --size " + std::to_string(w) + "x" + std::to_string(h), w, h,
               false);
  in.image = make_scene(scene, w, h);
  in.info.path = source = "scene:" + scene;
  return in;
}

std::uint64_t PipelineOptions::memory_budget() const {
  return max_memory.empty() ? default_memory_budget() : parse_byte_size(max_memory, "--max-memory");
}

void PipelineOptions::check_memory(const std::string& what, int width, int height,
                                   bool is_file) const {
  const std::uint64_t budget = memory_budget();
  const WorkingSet ws = working_set(params, width, height, kept_traces, gl);
  if (ws.bytes <= budget) return;
  const std::string problem =
      "a run over " + std::to_string(width) + "x" + std::to_string(height) + " (" +
      to_string(params.method) + ", " + to_string(params.precision) +
      (kept_traces > 0 ? ", every stage kept" : "") + ") needs up to " + byte_size_text(ws.bytes) +
      " (" + std::to_string(int(std::ceil(ws.images))) + " images of " +
      byte_size_text(ws.image_bytes) + " at once), beyond --max-memory " +
      byte_size_text(budget) +
      (max_memory.empty() ? " (the default: 80% of the " +
                                byte_size_text(available_memory_bytes()) + " available)"
                          : std::string()) +
      "; give a larger --max-memory, or a smaller image";
  if (is_file) throw InputError(what, problem);
  throw ParamError(what + ": " + problem);
}

void parse_size(const std::string& s, int& w, int& h) {
  const auto x = s.find('x');
  try {
    if (x == std::string::npos) throw std::invalid_argument("no x");
    std::size_t a = 0, b = 0;
    w = std::stoi(s.substr(0, x), &a);
    h = std::stoi(s.substr(x + 1), &b);
    if (a != x || b != s.size() - x - 1 || w < 1 || h < 1) throw std::invalid_argument("bad");
  } catch (const std::exception&) {
    throw ParamError("--size '" + s + "' is not WIDTHxHEIGHT with positive integers, e.g. 1920x1080");
  }
}

}  // namespace bloomref::cli
