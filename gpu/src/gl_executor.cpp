#include "bloomref/gpu/gl_executor.h"

#include <chrono>
#include <cmath>
#include <limits>

#include "bloomref/mip.h"
#include "bloomref/engine/support.h"
#include "gl_objects.h"

namespace bloomref::gpu {
namespace {

using Clock = std::chrono::steady_clock;

int policy_code(NonFinite n) {
  switch (n) {
    case NonFinite::zero: return 0;
    case NonFinite::clamp: return 1;
    case NonFinite::propagate: return 2;
    case NonFinite::error: return 3;
  }
  return 0;
}

std::vector<std::string> defines_for(const BloomParams& p, Fault fault, GLenum format) {
  std::vector<std::string> d;
  d.push_back(std::string("STORAGE_FORMAT ") + (format == GL_RGBA16F ? "rgba16f" : "rgba32f"));
  if (p.kernel == KernelName::linear5) d.push_back("KERNEL_LINEAR5 1");
  switch (fault) {
    case Fault::vertical_offsets_x: d.push_back("FAULT_VERTICAL_ALONG_X 1"); break;
    case Fault::half_texel_shift: d.push_back("FAULT_HALF_TEXEL 1"); break;
    case Fault::threshold_ge: d.push_back("FAULT_THRESHOLD_GE 1"); break;
    case Fault::weight_1pct: d.push_back("FAULT_WEIGHT_SCALE 1.01"); break;
    case Fault::weight_0_1pct: d.push_back("FAULT_WEIGHT_SCALE 1.001"); break;
    case Fault::weight_0_01pct: d.push_back("FAULT_WEIGHT_SCALE 1.0001"); break;
    case Fault::gamma_twice: d.push_back("FAULT_GAMMA_TWICE 1"); break;
    case Fault::swap_rb: d.push_back("FAULT_SWAP_RB 1"); break;
    case Fault::exposure_ignored: d.push_back("FAULT_NO_EXPOSURE 1"); break;
    case Fault::tap_offset: d.push_back("FAULT_TAP_OFFSET 1"); break;
    case Fault::karis_unnormalised: d.push_back("FAULT_KARIS_UNNORMALISED 1"); break;
    default: break;
  }
  return d;
}

Image to_image(const Texture& t) {
  Image img = Image::uninitialised(t.width, t.height);
  t.read(img.data());
  return img;
}

struct Rect {
  int x, y, w, h;
};

// The adaptive plan on the GL path: runs of active tiles of a texel mask, as scissor
// rectangles. A tile is active when a set texel lies in it or one texel outside it (a device
// whose coordinates round a tap one texel further than the CPU's tables still stays inside).
std::vector<Rect> active_rects(const std::uint8_t* mask, int w, int h, int tile,
                               std::size_t& area) {
  const int tw = (w + tile - 1) / tile, th = (h + tile - 1) / tile;
  std::vector<std::uint8_t> on(std::size_t(tw) * th, 0);
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* m = mask + std::size_t(y) * w;
    const int ty0 = std::max(y - 1, 0) / tile, ty1 = std::min(y + 1, h - 1) / tile;
    for (int x = 0; x < w; ++x) {
      if (!m[x]) continue;
      const int tx0 = std::max(x - 1, 0) / tile, tx1 = std::min(x + 1, w - 1) / tile;
      on[std::size_t(ty0) * tw + tx0] = on[std::size_t(ty0) * tw + tx1] = 1;
      on[std::size_t(ty1) * tw + tx0] = on[std::size_t(ty1) * tw + tx1] = 1;
    }
  }
  std::vector<Rect> rects;
  area = 0;
  for (int ty = 0; ty < th; ++ty) {
    for (int tx = 0; tx < tw;) {
      if (!on[std::size_t(ty) * tw + tx]) {
        ++tx;
        continue;
      }
      const int start = tx;
      while (tx < tw && on[std::size_t(ty) * tw + tx]) ++tx;
      const Rect r{start * tile, ty * tile, std::min(w, tx * tile) - start * tile,
                   std::min(h, (ty + 1) * tile) - ty * tile};
      area += std::size_t(r.w) * r.h;
      rects.push_back(r);
    }
  }
  return rects;
}

// Runs one stage program over the whole texture, as a draw or a dispatch.
class StageRunner {
 public:
  StageRunner(bool compute, GLenum format) : compute_(compute), format_(format) {
    glGenVertexArrays(1, &vao_);
    glBindVertexArray(vao_);
  }
  ~StageRunner() { glDeleteVertexArrays(1, &vao_); }

  /// Binds `inputs` to texture units 0.. and writes `out0` (and `out1`). With `rects`
  /// (fragment shaders only), the target is cleared to (0, 0, 0, 1) -- what the stage gives
  /// where the adaptive plan left it out -- and drawn inside the rectangles only.
  void run(const Program& prog, const std::vector<const Texture*>& inputs, const Texture& out0,
           const Texture* out1 = nullptr, const std::vector<Rect>* rects = nullptr) {
    glUseProgram(prog.id);
    if (!compute_) prog.set("u_target_size", out0.width, out0.height);
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      glActiveTexture(GL_TEXTURE0 + static_cast<GLenum>(i));
      glBindTexture(GL_TEXTURE_2D, inputs[i]->id);
    }
    if (compute_) {
      glBindImageTexture(0, out0.id, 0, GL_FALSE, 0, GL_WRITE_ONLY, format_);
      glBindImageTexture(1, (out1 ? out1 : &out0)->id, 0, GL_FALSE, 0, GL_WRITE_ONLY, format_);
      if (rects) {
        // Cleared, then one dispatch per rectangle (whole 8x8 groups: a texel past the
        // rectangle gets its true value, which is always right). GL orders the clear before
        // the image stores that follow it.
        clear(out0);
        for (const Rect& r : *rects) {
          prog.set("u_origin", r.x, r.y);
          glDispatchCompute((r.w + 7) / 8, (r.h + 7) / 8, 1);
        }
        prog.set("u_origin", 0, 0);
      } else {
        glDispatchCompute((out0.width + 7) / 8, (out0.height + 7) / 8, 1);
      }
      glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GL_TEXTURE_UPDATE_BARRIER_BIT);
    } else {
      Framebuffer fb(out0, out1);
      glViewport(0, 0, out0.width, out0.height);
      if (rects) {
        glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT);
        glEnable(GL_SCISSOR_TEST);
        for (const Rect& r : *rects) {
          glScissor(r.x, r.y, r.w, r.h);
          glDrawArrays(GL_TRIANGLES, 0, 3);
        }
        glDisable(GL_SCISSOR_TEST);
      } else {
        glDrawArrays(GL_TRIANGLES, 0, 3);
      }
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
    }
  }

  /// Writes (0, 0, 0, 1) to every texel of `out` (what a stage gives where everything it reads
  /// is +0), by a framebuffer clear for either shader kind.
  void clear(const Texture& out) {
    Framebuffer fb(out, nullptr);
    glViewport(0, 0, out.width, out.height);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }

 private:
  bool compute_;
  GLenum format_;
  GLuint vao_ = 0;
};

}  // namespace

StageTrace execute_gl(GlContext& ctx, const Plan& plan, ConstImageView scene,
                      const GlOptions& opt) {
  const BloomParams& p = plan.params;
  if (p.precision != Precision::f32)
    throw ParamError("--precision f64 is the CPU truth; the GL path computes in f32");
  const int w = scene.width, h = scene.height;
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (w > max_size || h > max_size)
    throw GlError("the image is " + std::to_string(w) + "x" + std::to_string(h) +
                  ", beyond this GL device's largest texture (" + std::to_string(max_size) + ")");
  const bool compute = opt.shaders == ShaderKind::compute;
  const bool f16 = p.storage == Storage::f16 || opt.fault == Fault::f16_storage;
  const GLenum fmt = f16 ? GL_RGBA16F : GL_RGBA32F;
  const std::vector<std::string> defs = defines_for(p, opt.fault, fmt);

  const Program extract = build_program(compute, "extract_bright.glsl", defs);
  const Program blur = build_program(compute, "blur_pass.glsl", defs);
  const Program comp = build_program(compute, "composite.glsl", defs);
  const Program tone = build_program(compute, "tonemap.glsl", defs);
  const Program encode = build_program(compute, "encode_output.glsl", defs);
  const bool mip = p.method == Method::mip;
  Program down_p, up_p;
  if (mip) {
    down_p = build_program(compute, "downsample.glsl", defs);
    up_p = build_program(compute, "upsample_tent.glsl", defs);
    down_p.set("src", 0);
    down_p.set("karis", p.karis ? 1 : 0);
    down_p.set("threshold", p.threshold);
    up_p.set("small", 0);
    up_p.set("current", 1);
  }
  ctx.check("building the stage programs");

  extract.set("raw", 0);
  extract.set("threshold", p.threshold);
  extract.set("policy", policy_code(p.nonfinite));
  extract.set("storage_max", static_cast<float>(storage_max(f16 ? Storage::f16 : Storage::f32)));
  extract.set("range_guard", static_cast<float>(kRangeGuard));
  blur.set("image", 0);
  comp.set("scene", 0);
  comp.set("bloom", 1);
  comp.set("strength", p.strength);
  tone.set("hdr", 0);
  tone.set("exposure", p.exposure);
  encode.set("mapped", 0);
  encode.set("gamma", p.gamma);

  // The scene goes up as the user's floats (RGBA32F), tightly packed.
  std::vector<float> packed(static_cast<std::size_t>(w) * h * kChannels);
  for (int y = 0; y < h; ++y)
    std::copy(scene.row(y), scene.row(y) + std::size_t(w) * kChannels,
              packed.begin() + std::size_t(y) * w * kChannels);
  Texture raw(w, h, GL_RGBA32F, packed.data());
  raw.set_sampling(GL_NEAREST, GL_CLAMP_TO_EDGE);
  Texture scene_t(w, h, fmt), bright_t(w, h, fmt), hdr_t(w, h, fmt), mapped_t(w, h, fmt),
      out_t(w, h, fmt);
  Texture ping[2] = {Texture(w, h, fmt), Texture(w, h, fmt)};
  std::vector<Texture> down_t, up_t;  // index k - 1 holds level k
  Texture bloom_t;
  if (mip) {
    for (std::size_t k = 0; k < plan.levels.size(); ++k) {
      const int extra = opt.fault == Fault::level_size && k == 1 ? 1 : 0;
      down_t.emplace_back(plan.levels[k].width + extra, plan.levels[k].height, fmt);
      up_t.emplace_back(plan.levels[k].width + extra, plan.levels[k].height, fmt);
    }
    bloom_t = Texture(w, h, fmt);
  }
  ctx.check("allocating the stage textures");

  StageRunner runner(compute, fmt);
  StageTrace trace;
  // The adaptive plan's texel support, as on the CPU, turned into rectangles of 64x64 tiles:
  // scissor rectangles for fragment shaders, one dispatch each for compute shaders. Faults run
  // whole.
  // Not for a dense scene (Plan::dense_scene): its support reaches most tiles at once.
  const bool scissor =
      p.plan == PlanMode::adaptive && !mip && opt.fault == Fault::none && !plan.dense_scene;
  constexpr int kScissorTile = 64;
  // Above half the image the readback, support and many draws cost more than the texels
  // saved (BrightRingsNanInf: 148 ms unscissored, 186 ms scissored on llvmpipe).
  BlurSupportTracker support(w, h, 0.5);
  // Method mip, adaptive plan: where no lookup of down.1 can reach the threshold (the CPU's own
  // test, mip.h), every chain stage is exactly (0, 0, 0, 1): cleared instead of drawn, both
  // shader kinds (the CPU plan leaves the same stages out). Faults run the whole chain.
  // The test is made on GL's own stored scene, as the CPU makes it on its stored scene; the
  // readback is done only where the user's scene passes it with a 2x margin (f16 storage
  // rounds by up to 2^-11, sanitising only removes what fails it anyway).
  const bool may_skip_mip = mip && p.plan == PlanMode::adaptive && opt.fault == Fault::none;
  bool mip_dark = false;  // decided by the input stage
  trace.nonfinite = plan.facts.nonfinite;
  const Texture* bloom = &bright_t;
  auto finish = [&](const std::string& name, const Texture& t, Clock::time_point t0,
                    bool skipped = false) {
    glFinish();
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ctx.check(name.c_str());
    if (!skipped) trace.timings.emplace_back(name, ms);
    if (opt.keep_all || name == "output") trace.stages.push_back({name, to_image(t), ms, skipped});
  };

  // A chain stage under mip_dark: its target cleared, the stage listed as skipped.
  auto cleared_dark = [&](const std::string& name, const Texture& target) {
    if (!mip_dark) return false;
    runner.clear(target);
    trace.skipped_fraction.emplace_back(name, 1.0);
    return true;
  };

  for (const StageSpec& s : plan.stages) {
    const auto t0 = Clock::now();
    switch (s.kind) {
      case StageKind::input:
        runner.run(extract, {&raw}, scene_t, &bright_t);
        mip_dark = may_skip_mip && mip_nothing_bright(scene, 0.5 * double(p.threshold), 0) &&
                   mip_nothing_bright(to_image(scene_t).cview(), double(p.threshold), 0);
        finish(s.name, scene_t, t0);
        break;
      case StageKind::bright:  // written by the input stage's draw
        finish(s.name, bright_t, t0);
        break;
      case StageKind::blur: {
        if (s.skipped) {
          if (opt.keep_all) finish(s.name, *bloom, t0, true);
          break;
        }
        Texture& target = ping[s.pass % 2];
        const Texture* src = bloom;
        std::vector<Rect> rects;
        const std::uint8_t* active = nullptr;
        if (scissor && !support.dense()) {
          // The CPU plan's texel support (stages.h), from GL's own bright image.
          if (!support.started()) support.start(to_image(bright_t).cview(), 0);
          const BlurPassOptions bo{s.axis, &kernel_for(p.kernel), p.subtexel_bits};
          active = support.advance<float>(bo, 0);
          std::size_t area = 0;
          if (active) rects = active_rects(active, w, h, kScissorTile, area);
          trace.skipped_fraction.emplace_back(
              s.name, active ? 1.0 - double(area) / (double(w) * h) : 0.0);
        }
        if (!(opt.fault == Fault::skip_pass && s.pass == 3)) {
          src->set_sampling(GL_LINEAR,
                            opt.fault == Fault::repeat_wrap ? GL_REPEAT : GL_CLAMP_TO_EDGE);
          blur.set("horizontal", s.axis == Axis::horizontal ? 1 : 0);
          runner.run(blur, {src}, target, nullptr, active ? &rects : nullptr);
        }
        bloom = &target;
        finish(s.name, target, t0);
        break;
      }
      case StageKind::down: {
        const int k = s.pass;
        if (!cleared_dark(s.name, down_t[k - 1])) {
          down_p.set("first_level", k == 1 ? 1 : 0);
          runner.run(down_p, {k == 1 ? &scene_t : &down_t[k - 2]}, down_t[k - 1]);
        }
        finish(s.name, down_t[k - 1], t0);
        break;
      }
      case StageKind::up: {
        const int k = s.pass, top = static_cast<int>(plan.levels.size());
        const Texture& small = k + 1 == top ? down_t[top - 1] : up_t[k];
        if (!cleared_dark(s.name, up_t[k - 1])) {
          up_p.set("has_current", 1);
          runner.run(up_p, {&small, &down_t[k - 1]}, up_t[k - 1]);
        }
        finish(s.name, up_t[k - 1], t0);
        break;
      }
      case StageKind::bloom: {
        const Texture& small = plan.levels.size() == 1 ? down_t[0] : up_t[0];
        if (!cleared_dark(s.name, bloom_t)) {
          up_p.set("has_current", 0);
          runner.run(up_p, {&small, &small}, bloom_t);
        }
        bloom = &bloom_t;
        finish(s.name, bloom_t, t0);
        break;
      }
      case StageKind::composite: {
        const bool after = mip && p.composite == CompositeOrder::after_tonemap;
        runner.run(comp, {after ? &mapped_t : &scene_t, bloom}, hdr_t);
        finish(s.name, hdr_t, t0);
        break;
      }
      case StageKind::tonemap:
        if (mip && p.composite == CompositeOrder::after_tonemap) {
          runner.run(tone, {&scene_t}, mapped_t);
        } else {
          runner.run(tone, {&hdr_t}, mapped_t);
        }
        finish(s.name, mapped_t, t0);
        break;
      case StageKind::output:
        runner.run(encode, {mip && p.composite == CompositeOrder::after_tonemap ? &hdr_t : &mapped_t},
                   out_t);
        finish(s.name, out_t, t0);
        break;
    }
  }
  // The plan's scan of the scene (on the CPU) is part of the run, as in the CPU executor.
  trace.timings.insert(trace.timings.begin(), {"plan", plan.facts.scan_ms});
  for (const auto& [name, ms] : trace.timings) trace.total_ms += ms;  // readbacks excluded
  return trace;
}

}  // namespace bloomref::gpu
