#include "bloomref/gpu/gl_executor.h"

#include <chrono>
#include <cmath>
#include <limits>

#include "bloomref/engine/support.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/mip.h"
#include "gl_objects.h"
#include "user_host.h"

namespace bloomref::gpu {
namespace {

using Clock = std::chrono::steady_clock;

std::vector<std::string> defines_for(const BloomParams& p, GLenum format) {
  std::vector<std::string> d;
  d.push_back(std::string("STORAGE_FORMAT ") + (format == GL_RGBA16F         ? "rgba16f"
                                                : format == GL_R11F_G11F_B10F ? "r11f_g11f_b10f"
                                                : format == GL_RGBA8          ? "rgba8"
                                                                              : "rgba32f"));
  if (p.kernel == KernelName::linear5) d.push_back("KERNEL_LINEAR5 1");
  if (p.luma == Luma::rec601) d.push_back("LUMA_REC601 1");
  if (p.luma_space == LumaSpace::srgb) d.push_back("LUMA_SRGB 1");
  if (p.luma_space == LumaSpace::gamma) d.push_back("LUMA_GAMMA 1");
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

// ---- How to schedule it --------------------------------------------------------------------

struct GlSchedule {
  bool compute = false;        // compute shaders (image stores), else fragment shaders (draws)
  GLenum format = GL_RGBA32F;  // every stage's textures: RGBA16F for f16 storage
  // Adaptive gaussian plan: each blur pass only inside the 64x64 tiles its texel support reaches
  // (as on the CPU): scissor rectangles for fragment shaders, one dispatch each for compute
  // shaders. Not for a dense scene (Plan::dense_scene): its support reaches most tiles at once.
  bool scissor = false;
  // Adaptive mip plan: where no lookup of down.1 can reach the threshold (the CPU's own test,
  // mip.h), every chain stage is exactly (0, 0, 0, 1): cleared instead of drawn, both shader
  // kinds (the CPU plan leaves the same stages out).
  bool may_skip_mip = false;
};

GlSchedule choose_gl_schedule(const Plan& plan, const GlOptions& opt) {
  const BloomParams& p = plan.params;
  // Faults run every stage whole.
  const bool adaptive = p.plan == PlanMode::adaptive && opt.fault == Fault::none;
  GlSchedule s;
  s.compute = opt.shaders == ShaderKind::compute;
  const bool f16 = p.storage == Storage::f16 || opt.fault == Fault::f16_storage;
  s.format = host::storage_format(f16 ? Storage::f16 : p.storage);
  s.scissor = adaptive && p.method == Method::gaussian && !plan.dense_scene;
  s.may_skip_mip = adaptive && p.method == Method::mip;
  return s;
}

// ---- The stages' programs and textures -----------------------------------------------------

struct StagePrograms {
  Program extract, blur, composite, tonemap, encode;
  Program down, up;  // method mip
};

// Compiles the stages' programs and sets the uniforms that stay fixed for the run.
StagePrograms build_programs(GlContext& ctx, const BloomParams& p, const GlSchedule& s,
                             Fault fault) {
  const std::vector<std::string> defs = defines_for(p, s.format);
  StagePrograms g;
  g.extract = build_program(s.compute, "extract_bright.glsl", defs, fault);
  g.blur = build_program(s.compute, "blur_pass.glsl", defs, fault);
  g.composite = build_program(s.compute, "composite.glsl", defs, fault);
  g.tonemap = build_program(s.compute, "tonemap.glsl", defs, fault);
  g.encode = build_program(s.compute, "encode_output.glsl", defs, fault);
  if (p.method == Method::mip) {
    g.down = build_program(s.compute, "downsample.glsl", defs, fault);
    g.up = build_program(s.compute, "upsample_tent.glsl", defs, fault);
    g.down.set("src", 0);
    g.down.set("karis", p.karis ? 1 : 0);
    g.down.set("threshold", p.threshold);
    g.down.set("luma_gamma", p.gamma);
    g.up.set("small", 0);
    g.up.set("current", 1);
  }
  ctx.check("building the stage programs");

  g.extract.set("raw", 0);
  g.extract.set("threshold", p.threshold);
  g.extract.set("luma_gamma", p.gamma);
  g.extract.set("policy", nonfinite_code(p.nonfinite));
  const bool f16 = s.format == GL_RGBA16F;
  g.extract.set("storage_max", static_cast<float>(storage_max(f16 ? Storage::f16 : p.storage)));
  g.extract.set("range_guard", static_cast<float>(kRangeGuard));
  g.blur.set("image", 0);
  g.composite.set("scene", 0);
  g.composite.set("bloom", 1);
  g.composite.set("strength", p.strength);
  g.tonemap.set("hdr", 0);
  g.tonemap.set("exposure", p.exposure);
  g.encode.set("mapped", 0);
  g.encode.set("gamma", p.gamma);
  return g;
}

struct StageTextures {
  Texture raw;  // the user's scene as given (RGBA32F)
  Texture scene, bright, hdr, mapped, out;
  Texture ping[2];                // blur pass k writes ping[k % 2]
  std::vector<Texture> down, up;  // method mip: index k - 1 holds level k
  Texture bloom;                  // method mip
};

StageTextures make_textures(GlContext& ctx, const Plan& plan, ConstImageView scene, GLenum fmt,
                            Fault fault) {
  const int w = scene.width, h = scene.height;
  // The scene goes up as the user's floats (RGBA32F), tightly packed.
  std::vector<float> packed(static_cast<std::size_t>(w) * h * kChannels);
  for (int y = 0; y < h; ++y)
    std::copy(scene.row(y), scene.row(y) + std::size_t(w) * kChannels,
              packed.begin() + std::size_t(y) * w * kChannels);
  StageTextures t;
  t.raw = Texture(w, h, GL_RGBA32F, packed.data());
  t.raw.set_sampling(GL_NEAREST, GL_CLAMP_TO_EDGE);
  for (Texture* x : {&t.scene, &t.bright, &t.hdr, &t.mapped, &t.out, &t.ping[0], &t.ping[1]})
    *x = Texture(w, h, fmt);
  if (plan.params.method == Method::mip) {
    for (std::size_t k = 0; k < plan.levels.size(); ++k) {
      const int extra = fault == Fault::level_size && k == 1 ? 1 : 0;
      t.down.emplace_back(plan.levels[k].width + extra, plan.levels[k].height, fmt);
      t.up.emplace_back(plan.levels[k].width + extra, plan.levels[k].height, fmt);
    }
    t.bloom = Texture(w, h, fmt);
  }
  ctx.check("allocating the stage textures");
  return t;
}

// ---- The algorithm: one function per stage -------------------------------------------------

class GlExecutor {
 public:
  GlExecutor(GlContext& ctx, const Plan& plan, ConstImageView scene, const GlOptions& opt)
      : ctx_(ctx),
        plan_(plan),
        p_(plan.params),
        opt_(opt),
        scene_(scene),
        w_(scene.width),
        h_(scene.height),
        sched_(choose_gl_schedule(plan, opt)),
        progs_(build_programs(ctx, plan.params, sched_, opt.fault)),
        tex_(make_textures(ctx, plan, scene, sched_.format, opt.fault)),
        runner_(sched_.compute, sched_.format),
        support_(scene.width, scene.height, 0.5) {
    glGenQueries(1, &query_);
  }
  ~GlExecutor() {
    if (query_open_) glEndQuery(GL_TIME_ELAPSED);
    glDeleteQueries(1, &query_);
  }
  GlExecutor(const GlExecutor&) = delete;
  GlExecutor& operator=(const GlExecutor&) = delete;

  StageTrace run() {
    trace_.nonfinite = plan_.facts.nonfinite;
    for (const StageSpec& s : plan_.stages) {
      const auto t0 = Clock::now();
      glBeginQuery(GL_TIME_ELAPSED, query_);  // the stage's commands on the device
      query_open_ = true;
      switch (s.kind) {
        case StageKind::input:
          input(s, t0);
          break;
        case StageKind::bright:  // written by the input stage's draw
          finish(s.name, tex_.bright, t0);
          break;
        case StageKind::blur:
          blur(s, t0);
          break;
        case StageKind::down:
          down(s, t0);
          break;
        case StageKind::up:
          up(s, t0);
          break;
        case StageKind::bloom:
          mip_bloom(s, t0);
          break;
        case StageKind::composite:
          composite(s, t0);
          break;
        case StageKind::tonemap:
          tonemap(s, t0);
          break;
        case StageKind::output:
          output(s, t0);
          break;
      }
      if (query_open_) {  // a stage that ended without finish (a skipped pass not kept)
        glEndQuery(GL_TIME_ELAPSED);
        query_open_ = false;
      }
    }
    // A timer that did not time every stage times none (docs/design.md, "Device time").
    if (!timer_sound_) trace_.device_timings.clear();
    // The plan's scan of the scene (on the CPU) is part of the run, as in the CPU executor.
    trace_.timings.insert(trace_.timings.begin(), {"plan", plan_.facts.scan_ms});
    for (const auto& [name, ms] : trace_.timings) trace_.total_ms += ms;  // readbacks excluded
    return std::move(trace_);
  }

 private:
  static constexpr int kScissorTile = 64;

  // Ends a stage: its time (after glFinish; readbacks excluded) and, when kept, its image.
  void finish(const std::string& name, const Texture& t, Clock::time_point t0,
              bool skipped = false) {
    const bool timed = query_open_;
    if (query_open_) glEndQuery(GL_TIME_ELAPSED);
    query_open_ = false;
    glFinish();
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ctx_.check(name.c_str());
    if (!skipped) trace_.timings.emplace_back(name, ms);
    if (!skipped && timed && name != "bright") {  // bright: no commands, the input's draw
      GLuint64 ns = 0;
      glGetQueryObjectui64v(query_, GL_QUERY_RESULT, &ns);
      const double device_ms = double(ns) * 1e-6;
      // A stage with commands takes some time, and no more than its wall time: otherwise the
      // query did not time it (llvmpipe's do not time compute dispatches).
      timer_sound_ = timer_sound_ && device_ms > 0 && device_ms <= ms * 1.01 + 0.05;
      trace_.device_timings.emplace_back(name, device_ms);
    }
    if (opt_.keep_all || name == "output")
      trace_.stages.push_back({name, to_image(t), ms, skipped});
  }

  // Stage input (and bright, the same draw's second target). The mip chain's dark test is made
  // on GL's own stored scene, as the CPU makes it on its stored scene; the readback is done only
  // where the user's scene passes it with a 2x margin (f16 storage rounds by up to 2^-11,
  // sanitising only removes what fails it anyway).
  void input(const StageSpec& s, Clock::time_point t0) {
    runner_.run(progs_.extract, {&tex_.raw}, tex_.scene, &tex_.bright);
    mip_dark_ = sched_.may_skip_mip &&
                mip_nothing_bright(scene_, 0.5 * double(p_.threshold), 0, luma_rule(p_)) &&
                mip_nothing_bright(to_image(tex_.scene).cview(), double(p_.threshold), 0,
                                   luma_rule(p_));
    finish(s.name, tex_.scene, t0);
  }

  void blur(const StageSpec& s, Clock::time_point t0) {
    if (s.skipped) {
      if (opt_.keep_all) finish(s.name, *bloom_, t0, true);
      return;
    }
    Texture& target = tex_.ping[s.pass % 2];
    std::vector<Rect> rects;
    const bool scissored = sched_.scissor && !support_.dense() && support_rects(s, rects);
    if (!(opt_.fault == Fault::skip_pass && s.pass == 3)) {
      bloom_->set_sampling(GL_LINEAR,
                           opt_.fault == Fault::repeat_wrap ? GL_REPEAT : GL_CLAMP_TO_EDGE);
      progs_.blur.set("horizontal", s.axis == Axis::horizontal ? 1 : 0);
      runner_.run(progs_.blur, {bloom_}, target, nullptr, scissored ? &rects : nullptr);
    }
    bloom_ = &target;
    finish(s.name, target, t0);
  }

  // The CPU plan's texel support of this pass (stages.h), from GL's own bright image, as
  // rectangles of tiles; false (draw it all) once it covers half the image, where the readback,
  // support and many draws cost more than the texels saved (docs/design.md, "The GL path uses
  // the adaptive plan's support").
  bool support_rects(const StageSpec& s, std::vector<Rect>& rects) {
    if (!support_.started()) support_.start(to_image(tex_.bright).cview(), 0);
    const BlurPassOptions bo{s.axis, &kernel_for(p_.kernel), p_.subtexel_bits};
    const std::uint8_t* active = support_.advance<float>(bo, 0);
    std::size_t area = 0;
    if (active) rects = active_rects(active, w_, h_, kScissorTile, area);
    trace_.skipped_fraction.emplace_back(s.name,
                                         active ? 1.0 - double(area) / (double(w_) * h_) : 0.0);
    return active != nullptr;
  }

  // A mip chain stage under mip_dark_: its target cleared, the stage listed as skipped.
  bool cleared_dark(const std::string& name, const Texture& target) {
    if (!mip_dark_) return false;
    runner_.clear(target);
    trace_.skipped_fraction.emplace_back(name, 1.0);
    return true;
  }

  void down(const StageSpec& s, Clock::time_point t0) {
    const int k = s.pass;
    if (!cleared_dark(s.name, tex_.down[k - 1])) {
      progs_.down.set("first_level", k == 1 ? 1 : 0);
      runner_.run(progs_.down, {k == 1 ? &tex_.scene : &tex_.down[k - 2]}, tex_.down[k - 1]);
    }
    finish(s.name, tex_.down[k - 1], t0);
  }

  void up(const StageSpec& s, Clock::time_point t0) {
    const int k = s.pass, top = static_cast<int>(plan_.levels.size());
    // Level k + 1's result (the deepest level's downsample); with the fault, level 2 reads the
    // one after it.
    const int read = opt_.fault == Fault::level_offset && k == 2 && top >= 4 ? k + 1 : k;
    const Texture& small = read + 1 == top ? tex_.down[top - 1] : tex_.up[read];
    if (!cleared_dark(s.name, tex_.up[k - 1])) {
      progs_.up.set("has_current", 1);
      runner_.run(progs_.up, {&small, &tex_.down[k - 1]}, tex_.up[k - 1]);
    }
    finish(s.name, tex_.up[k - 1], t0);
  }

  void mip_bloom(const StageSpec& s, Clock::time_point t0) {
    const Texture& small = plan_.levels.size() == 1 ? tex_.down[0] : tex_.up[0];
    if (!cleared_dark(s.name, tex_.bloom)) {
      progs_.up.set("has_current", 0);
      runner_.run(progs_.up, {&small, &small}, tex_.bloom);
    }
    bloom_ = &tex_.bloom;
    finish(s.name, tex_.bloom, t0);
  }

  // Method mip, after-tonemap (seed 003): the bloom is added to the tone-mapped scene and the
  // output encodes that sum.
  bool after_tonemap() const {
    return p_.method == Method::mip && p_.composite == CompositeOrder::after_tonemap;
  }

  void composite(const StageSpec& s, Clock::time_point t0) {
    runner_.run(progs_.composite, {after_tonemap() ? &tex_.mapped : &tex_.scene, bloom_}, tex_.hdr);
    finish(s.name, tex_.hdr, t0);
  }

  void tonemap(const StageSpec& s, Clock::time_point t0) {
    runner_.run(progs_.tonemap, {after_tonemap() ? &tex_.scene : &tex_.hdr}, tex_.mapped);
    finish(s.name, tex_.mapped, t0);
  }

  void output(const StageSpec& s, Clock::time_point t0) {
    runner_.run(progs_.encode, {after_tonemap() ? &tex_.hdr : &tex_.mapped}, tex_.out);
    finish(s.name, tex_.out, t0);
  }

  GlContext& ctx_;
  const Plan& plan_;
  const BloomParams& p_;
  const GlOptions& opt_;
  const ConstImageView scene_;
  const int w_, h_;
  const GlSchedule sched_;
  const StagePrograms progs_;
  StageTextures tex_;
  StageRunner runner_;
  StageTrace trace_;
  BlurSupportTracker support_;  // adaptive plan (sched_.scissor): the blur's texel support
  bool mip_dark_ = false;       // decided by the input stage
  GLuint query_ = 0;         // GL_TIME_ELAPSED around each stage's commands
  bool query_open_ = false;
  bool timer_sound_ = true;  // every stage's query result within (0, its wall time]
  // What the composite adds: the last blur pass, the mip chain's bloom, or (no pass ran) bright.
  const Texture* bloom_ = &tex_.bright;
};

}  // namespace

StageTrace execute_gl(GlContext& ctx, const Plan& plan, ConstImageView scene,
                      const GlOptions& opt) {
  if (plan.params.precision != Precision::f32)
    throw ParamError("--precision f64 is the CPU truth; the GL path computes in f32");
  if (plan.params.mip_variant() || plan.params.composite_mode != CompositeMode::add) {
    // A preset's chain: its host code as a description around bloomref's shaders for it.
    if (opt.fault != Fault::none || opt.shaders != ShaderKind::fragment)
      throw ParamError("--inject-fault and --gl-shaders compute apply to bloomref's own pipeline "
                       "shaders; a mip-chain variant runs its preset's fragment passes");
    return run_described(ctx, scene,
                         preset_description(plan.params, scene.width, scene.height), plan.params)
        .trace;
  }
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (scene.width > max_size || scene.height > max_size)
    throw GlError("the image is " + std::to_string(scene.width) + "x" +
                  std::to_string(scene.height) + ", beyond this GL device's largest texture (" +
                  std::to_string(max_size) + ")");
  return GlExecutor(ctx, plan, scene, opt).run();
}

}  // namespace bloomref::gpu
