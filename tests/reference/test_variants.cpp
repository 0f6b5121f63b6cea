// The mip-chain variants' pieces against hand calculation: the packed-float storage of an
// R11F_G11F_B10F level, GLSL's mix, the host's halved float sizes, the bright prefilter in the
// plan, and the options a preset's variant gives each downsample. The whole chain against an
// independent numpy computation is tests/cli/test_variants_numpy.py.
#include <catch2/catch.hpp>
#include <cmath>
#include <functional>

#include "bloomref/half.h"
#include "bloomref/mip.h"
#include "bloomref/plan.h"
#include "bloomref/stages.h"

using namespace bloomref;

TEST_CASE("R11F_G11F_B10F rounding: 6-bit mantissas (5 for blue), no sign, saturating", "[variants]") {
  // 2.0234375 = 2 + 0.75 of the quantum 2^(1-6) = 1/32 at 2: nearest 2 + 1/32, truncated 2
  // (what llvmpipe stores, docs/design.md).
  CHECK(round_to_packed(2.0234375, 6, false) == 2.03125);
  CHECK(round_to_packed(2.0234375, 6, true) == 2.0);
  // Blue: 5 bits, quantum 1/16 at 2: 2.0234375 is 0.375 of it: 2 either way.
  CHECK(round_to_packed(2.0234375, 5, false) == 2.0);
  // 4.1171875 = 4 + 0.1171875, blue quantum at 4 is 1/8: 0.9375 of it: nearest 4.125, truncated 4.
  CHECK(round_to_packed(4.1171875, 5, false) == 4.125);
  CHECK(round_to_packed(4.1171875, 5, true) == 4.0);
  // No sign: negative values are 0; NaN stays NaN (the format has NaNs).
  CHECK(round_to_packed(-3.0, 6, false) == 0.0);
  CHECK(std::isnan(round_to_packed(NAN, 6, false)));
  // Largest finite: (2 - 2^-6) 2^15 = 65024 for R and G, (2 - 2^-5) 2^15 = 64512 for B.
  CHECK(round_to_packed(1e9, 6, false) == 65024.0);
  CHECK(round_to_packed(1e9, 5, true) == 64512.0);
  // Denormals below 2^-14 have the quantum 2^(-14-6) = 2^-20: 3 2^-20 is exact, 3.5 2^-20 is not.
  CHECK(round_to_packed(std::ldexp(3.0, -20), 6, false) == std::ldexp(3.0, -20));
  CHECK(round_to_packed(std::ldexp(3.5, -20), 6, true) == std::ldexp(3.0, -20));
  // Ties go away from zero: 1 + 1.5 quanta (1/64 at 1) rounds to 1 + 2/64.
  CHECK(round_to_packed(1.0 + 1.5 / 64, 6, false) == 1.0 + 2.0 / 64);
}

TEST_CASE("store r11g11b10 rounds R, G with 6 bits and B with 5, and reads alpha back as 1", "[variants]") {
  Image img(1, 1);
  float* p = img.pixel(0, 0);
  p[0] = 2.0234375f, p[1] = -1.0f, p[2] = 4.1171875f, p[3] = 0.25f;
  store(img.view(), Storage::r11g11b10, HalfRounding::toward_zero, 1);
  CHECK(p[0] == 2.0f);
  CHECK(p[1] == 0.0f);
  CHECK(p[2] == 4.0f);
  CHECK(p[3] == 1.0f);
  p[0] = 2.0234375f, p[2] = 4.1171875f;
  store(img.view(), Storage::r11g11b10, HalfRounding::nearest_even, 1);
  CHECK(p[0] == 2.03125f);
  CHECK(p[2] == 4.125f);
}

TEST_CASE("composite_mix is GLSL's mix: scene (1 - a) + bloom a", "[variants]") {
  Image scene(2, 1), bloom(2, 1), out(2, 1);
  scene.pixel(0, 0)[0] = 1.0f, bloom.pixel(0, 0)[0] = 3.0f;      // 0.75 + 0.75 = 1.5
  scene.pixel(1, 0)[2] = 100.0f, bloom.pixel(1, 0)[2] = 0.0f;    // 96
  scene.pixel(1, 0)[3] = 0.5f;                                   // alpha is the scene's
  composite_mix(scene.cview(), bloom.cview(), out.view(), 0.25f, 1);
  CHECK(out.pixel(0, 0)[0] == 1.5f);
  CHECK(out.pixel(1, 0)[2] == 75.0f);
  CHECK(out.pixel(1, 0)[3] == 0.5f);
  composite_mix(scene.cview(), bloom.cview(), out.view(), 0.04f, 1);
  // 100 (1 - 0.04f) in float: 1 - 0.04f = 0.96000000834465 rounds to 0.96000003815; times 100.
  CHECK(out.pixel(1, 0)[2] == static_cast<float>(100.0f * (1.0f - 0.04f)));
}

TEST_CASE("the host's float sizes halve exactly, the texture's are floored", "[variants]") {
  CHECK(halved_size(1262, 0) == 1262.0f);
  CHECK(halved_size(1262, 2) == 315.5f);
  CHECK(halved_size(1262, 3) == 157.75f);
  const std::vector<LevelSize> l = mip_levels(1262, 860, 6);
  REQUIRE(l.size() == 6);
  CHECK(l[2].width == 157);  // (int)(1262 * 0.5^3) = 157
  CHECK(l[2].height == 107);
  BloomParams p;
  p.method = Method::mip;
  p.texel_step = TexelStep::halved_float;
  const DownsampleOptions o = downsample_options(p, 4, 1262, 860, 0);
  CHECK(o.step_width == 157.75f);   // down.4 reads level 3, 157 texels, with the host's 157.75
  CHECK(o.step_height == 107.5f);
  CHECK_FALSE(o.first);
  p.texel_step = TexelStep::texture;
  CHECK(downsample_options(p, 4, 1262, 860, 0).step_width == 0.0f);  // the texture's own
}

TEST_CASE("the bright prefilter puts a bright stage before the chain, which then thresholds nothing", "[variants]") {
  BloomParams p;
  p.method = Method::mip;
  p.levels = 2;
  std::vector<std::string> names = stage_names(p, 64, 64);
  CHECK(names[1] == "down.1");
  p.prefilter = Prefilter::bright;
  names = stage_names(p, 64, 64);
  REQUIRE(names.size() > 2);
  CHECK(names[1] == "bright");
  CHECK(names[2] == "down.1");
  CHECK_FALSE(downsample_options(p, 1, 64, 64, 0).threshold_taps);
  // A constant 0.5 (below the threshold 1) through the first downsample: thresholded per lookup
  // it is 0; read as a thresholded image (prefilter bright), the chain keeps it: 0.5.
  Image src(8, 8), dst(4, 4);
  for (float& v : src.values()) v = 0.5f;
  p.prefilter = Prefilter::per_lookup;
  downsample(src.cview(), dst.view(), downsample_options(p, 1, 8, 8, 0), 1);
  CHECK(dst.pixel(1, 1)[0] == 0.0f);
  p.prefilter = Prefilter::bright;
  downsample(src.cview(), dst.view(), downsample_options(p, 1, 8, 8, 0), 1);
  CHECK(dst.pixel(1, 1)[0] == Approx(0.5f).epsilon(1e-6));
}

TEST_CASE("variant options are refused outside the mip method, and a mix needs a strength in [0, 1]", "[variants]") {
  BloomParams p;
  p.prefilter = Prefilter::bright;
  CHECK_THROWS_WITH(refuse_ignored_options(p), Catch::Contains("nothing without --method mip"));
  // Given by name: refused even at seed 002's value; a preset's (not given) are not.
  p = BloomParams{};
  CHECK_THROWS_WITH(refuse_ignored_options(p, [](const std::string& o) { return o == "--downsample"; }),
                    Catch::Contains("--downsample does nothing without --method mip"));
  p.karis = true;
  p.prefilter = Prefilter::bright;
  CHECK_NOTHROW(refuse_ignored_options(p, [](const std::string&) { return false; }));
  p = BloomParams{};
  p.composite_mode = CompositeMode::mix;
  p.strength = 2.0f;
  CHECK_THROWS_WITH(validate(p), Catch::Contains("[0, 1]"));
  // Every storage is one of every stage (the levels' own with --chain-storage).
  for (Storage st : {Storage::r11g11b10, Storage::rgba8}) {
    p = BloomParams{};
    p.storage = st;
    CHECK_NOTHROW(validate(p));
    CHECK(parse_storage(to_string(st)) == st);
  }
  CHECK_THROWS_WITH(parse_storage("rgb565"), Catch::Contains("--storage"));
}

TEST_CASE("an option that only its mode reads is refused without that mode", "[variants]") {
  struct Case {
    const char* option;
    Method method;                           // where the option means nothing
    std::function<void(BloomParams&)> set;   // the option, changed from its default
    std::function<void(BloomParams&)> mode;  // the mode that reads it
  };
  const auto mip = Method::mip;
  const std::vector<Case> cases = {
      {"--levels", Method::gaussian, [](BloomParams& p) { p.levels = 4; },
       [](BloomParams& p) { p.method = Method::mip; }},
      {"--passes", mip, [](BloomParams& p) { p.passes = 4; },
       [](BloomParams& p) { p.method = Method::gaussian; }},
      {"--kernel", mip, [](BloomParams& p) { p.kernel = KernelName::linear5; },
       [](BloomParams& p) { p.method = Method::gaussian; }},
      {"--karis-form", mip, [](BloomParams& p) { p.karis_form = KarisForm::group_linear; },
       [](BloomParams& p) { p.karis = true; }},
      {"--knee", mip, [](BloomParams& p) { p.knee = 0.5f; },
       [](BloomParams& p) { p.prefilter = Prefilter::soft_knee; }},
      {"--knee-form", mip, [](BloomParams& p) { p.knee_form = KneeForm::unity; },
       [](BloomParams& p) { p.prefilter = Prefilter::soft_knee; }},
      {"--smooth-width", mip, [](BloomParams& p) { p.smooth_width = 0.1f; },
       [](BloomParams& p) {
         p.prefilter = Prefilter::smoothstep;
         p.first_downsample = FirstDownsample::bilinear;
       }},
      {"--level-kernels", mip, [](BloomParams& p) { p.level_kernels = {3, 5, 7, 9, 11}; },
       [](BloomParams& p) { p.downsample = DownsampleFilter::separable; }},
      {"--level-sigmas", mip, [](BloomParams& p) { p.level_sigmas = {2.0f}; },
       [](BloomParams& p) { p.downsample = DownsampleFilter::separable; }},
      {"--level-normalise", mip, [](BloomParams& p) { p.level_normalise = true; },
       [](BloomParams& p) { p.downsample = DownsampleFilter::separable; }},
      {"--level-weight", mip, [](BloomParams& p) { p.level_weight = 0.5f; },
       [](BloomParams& p) { p.level_weights = LevelWeights::constant; }},
      {"--low-frequency-boost", mip, [](BloomParams& p) { p.low_frequency_boost = 0.2f; },
       [](BloomParams& p) { p.level_weights = LevelWeights::bevy; }},
      {"--low-frequency-boost-curvature", mip,
       [](BloomParams& p) { p.low_frequency_boost_curvature = 0.5f; },
       [](BloomParams& p) { p.level_weights = LevelWeights::bevy; }},
      {"--high-pass-frequency", mip, [](BloomParams& p) { p.high_pass_frequency = 0.5f; },
       [](BloomParams& p) { p.level_weights = LevelWeights::bevy; }},
      {"--first-axis", mip, [](BloomParams& p) { p.first_axis = FirstAxis::vertical; },
       [](BloomParams& p) { p.method = Method::gaussian; }},
      {"--subtexel-bits", Method::gaussian,
       [](BloomParams& p) {
         p.subtexel_bits = 8;
         p.precision = Precision::f64;
       },
       [](BloomParams& p) { p.precision = Precision::f32; }},
      {"--threshold", mip,
       [](BloomParams& p) {
         p.threshold = 0.5f;
         p.prefilter = Prefilter::none;
       },
       [](BloomParams& p) { p.prefilter = Prefilter::bright; }},
      {"--luma", mip,
       [](BloomParams& p) {
         p.luma = Luma::rec601;
         p.prefilter = Prefilter::soft_knee;
       },
       [](BloomParams& p) { p.prefilter = Prefilter::per_lookup; }},
      {"--first-level-height", mip,
       [](BloomParams& p) {
         p.first_level_height = 64;
         p.level_count = LevelCount::unity;
       },
       [](BloomParams& p) { p.level_count = LevelCount::fixed; }},
  };
  for (const Case& c : cases) {
    INFO(c.option);
    BloomParams p;
    p.method = c.method;
    c.set(p);
    CHECK_THROWS_WITH(refuse_ignored_options(p), Catch::Contains(c.option) && Catch::Contains("does nothing"));
    // given on the command line: refused too; left by a preset whose mode was overridden: not
    CHECK_THROWS(refuse_ignored_options(p, [&](const std::string& o) { return o == c.option; }));
    CHECK_NOTHROW(refuse_ignored_options(p, [](const std::string&) { return false; }));
    c.mode(p);
    CHECK_NOTHROW(validate(p));
    CHECK_NOTHROW(refuse_ignored_options(p));
  }
  // three.js's sum options need the sum, which needs its level count
  for (const char* option : {"--level-factors", "--level-radius", "--level-strength"}) {
    INFO(option);
    BloomParams p;
    p.method = Method::mip;
    const std::string o = option;
    if (o == "--level-factors") p.level_factors = {1, 1, 1, 1, 1, 1};
    if (o == "--level-radius") p.level_radius = 0.5f;
    if (o == "--level-strength") p.level_strength = 2.0f;
    CHECK_THROWS_WITH(refuse_ignored_options(p), Catch::Contains(option) && Catch::Contains("does nothing"));
    p.level_combine = LevelCombine::sum;
    p.level_count = LevelCount::threejs;
    p.first_downsample = FirstDownsample::bilinear;
    p.prefilter = Prefilter::bright;
    p.levels = 5;
    CHECK_NOTHROW(validate(p));
    CHECK_NOTHROW(refuse_ignored_options(p));
  }
  // ... and under the sum there are no upsamples: what blends or reads them is refused.
  BloomParams s;
  s.method = Method::mip;
  s.level_combine = LevelCombine::sum;
  s.level_count = LevelCount::threejs;
  s.first_downsample = FirstDownsample::bilinear;
  s.prefilter = Prefilter::bright;
  s.levels = 5;
  s.bloom_upscale = BloomUpscale::bilinear;
  CHECK_NOTHROW(refuse_ignored_options(s));
  BloomParams t = s;
  t.level_weights = LevelWeights::constant;
  CHECK_THROWS_WITH(refuse_ignored_options(t), Catch::Contains("--level-weights does nothing"));
  t = s;
  t.upsample = UpsampleFilter::bilinear;
  CHECK_THROWS_WITH(refuse_ignored_options(t), Catch::Contains("--upsample does nothing"));
  t = s;
  t.upsample_radius = 0.01f;
  CHECK_THROWS_WITH(refuse_ignored_options(t), Catch::Contains("--upsample-radius does nothing"));
  t.bloom_upscale = BloomUpscale::tent;  // the full-size bloom's tent reads it
  CHECK_NOTHROW(refuse_ignored_options(t));
}
