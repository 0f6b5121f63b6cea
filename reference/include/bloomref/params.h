// bloomref — the parameters of one bloom run, and their validation.
// Defaults are the seeds' (LearnOpenGL "Bloom", ../shared/seeds/000): threshold 1, 10 passes,
// exposure 1, gamma 2.2. Validation refuses bad values with a ParamError naming the parameter;
// nothing is clamped silently.
#pragma once

#include <string>
#include <vector>

namespace bloomref {

enum class Method { gaussian, mip };
enum class KernelName { discrete9, linear5 };
/// How every stage's output is stored, as the GL path stores it (RGBA32F / RGBA16F).
enum class Storage { f32, f16 };
/// f32 mirrors the shaders' operation order; f64 is the truth used to measure error.
enum class Precision { f32, f64 };
/// What happens to NaN and +-Inf in the input (docs/design.md, "Specification").
enum class NonFinite { zero, clamp, propagate, error };
/// `adaptive` leaves out work the scene does not need (same bits as `full`).
enum class PlanMode { adaptive, full };
/// How the f32 gaussian blur is computed: `fast` (tiled and vectorised, blur_pass_fast) and
/// `reference` (the straightforward per-texel loop, blur_pass) give the same bits; `approx`
/// (blur_pass_approx) is faster and not GL's sampling: its error is measured, not assumed.
/// f64 always uses the reference loop.
enum class BlurImpl { fast, reference, approx };
/// Where the bloom is added: to the HDR scene before the tone map (the classic, seed 000), or to
/// the tone-mapped image (seed 003: mapped + 0.02 * bloom with exposure 0.5).
enum class CompositeOrder { before_tonemap, after_tonemap };

struct BloomParams {
  Method method = Method::gaussian;
  float threshold = 1.0f;   ///< bright when luminance > threshold (strictly)
  float exposure = 1.0f;    ///< tone map: 1 - exp(-hdr * exposure)
  float gamma = 2.2f;       ///< output: pow(max(x, 0), 1 / gamma)
  float strength = 1.0f;    ///< composite: scene + strength * bloom
  int passes = 10;          ///< single-direction blur passes; pass k is horizontal when k is odd
  KernelName kernel = KernelName::discrete9;
  Storage storage = Storage::f32;
  Precision precision = Precision::f32;
  NonFinite nonfinite = NonFinite::zero;
  /// Sub-texel precision of bilinear weights: 0 = exact float weights (llvmpipe, measured),
  /// 8 = 8-bit fixed point (NVIDIA-like hardware). Only the f32 precision uses it.
  int subtexel_bits = 0;
  int threads = 0;  ///< 0 = all hardware threads
  PlanMode plan = PlanMode::adaptive;
  BlurImpl blur = BlurImpl::fast;
  // Method mip (seed 003):
  int levels = 6;           ///< downsample levels; fewer when the image reaches 1x1
  bool karis = false;       ///< Karis average on the first downsample
  CompositeOrder composite = CompositeOrder::before_tonemap;
};

/// Throws ParamError for the first value out of its domain.
void validate(const BloomParams& p);

// Names used by the CLI, JSON and files. parse_* throw ParamError listing the accepted names.
std::string to_string(Method m);
std::string to_string(KernelName k);
std::string to_string(Storage s);
std::string to_string(Precision p);
std::string to_string(NonFinite n);
std::string to_string(PlanMode m);
std::string to_string(BlurImpl b);
std::string to_string(CompositeOrder c);
Method parse_method(const std::string& s);
KernelName parse_kernel(const std::string& s);
Storage parse_storage(const std::string& s);
Precision parse_precision(const std::string& s);
NonFinite parse_nonfinite(const std::string& s);
PlanMode parse_plan_mode(const std::string& s);
BlurImpl parse_blur_impl(const std::string& s);
CompositeOrder parse_composite_order(const std::string& s);

}  // namespace bloomref
