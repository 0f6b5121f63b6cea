#include "bloomref/vulkan/executor.h"

#include <Imath/half.h>

#include <chrono>
#include <cstring>
#include <memory>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "bloomref/vulkan/described.h"
#include "stage_program.h"
#include "vk_objects.h"

namespace bloomref::vulkan {
namespace {

using Clock = std::chrono::steady_clock;

class VulkanExecutor {
 public:
  VulkanExecutor(Context& ctx, const Plan& plan, ConstImageView scene, const SourceEdit& edit,
                 const HostFaults& faults)
      : ctx_(ctx.impl()), plan_(plan), p_(plan.params), scene_(scene), w_(scene.width),
        h_(scene.height), faults_(faults), f16_(p_.storage == Storage::f16 || faults.f16_storage),
        format_(f16_ ? VK_FORMAT_R16G16B16A16_SFLOAT : VK_FORMAT_R32G32B32A32_SFLOAT),
        sampler_(ctx_, VK_FILTER_LINEAR), blur_sampler_(ctx_, VK_FILTER_LINEAR, faults.repeat_wrap) {
    std::vector<std::string> defs = {std::string("STORAGE_FORMAT ") + (f16_ ? "rgba16f" : "rgba32f")};
    if (p_.kernel == KernelName::linear5) defs.push_back("KERNEL_LINEAR5 1");
    if (p_.luma == Luma::rec601) defs.push_back("LUMA_REC601 1");
    if (p_.luma_space == LumaSpace::srgb) defs.push_back("LUMA_SRGB 1");
    if (p_.luma_space == LumaSpace::gamma) defs.push_back("LUMA_GAMMA 1");
    extract_ = std::make_unique<StageProgram>(ctx_, "extract_bright.glsl", defs, edit);
    blur_ = std::make_unique<StageProgram>(ctx_, "blur_pass.glsl", defs, edit);
    composite_ = std::make_unique<StageProgram>(ctx_, "composite.glsl", defs, edit);
    tonemap_ = std::make_unique<StageProgram>(ctx_, "tonemap.glsl", defs, edit);
    encode_ = std::make_unique<StageProgram>(ctx_, "encode_output.glsl", defs, edit);
    extract_->set("threshold", p_.threshold);
    extract_->set("luma_gamma", p_.gamma);
    extract_->set_int("policy", nonfinite_code(p_.nonfinite));
    extract_->set("storage_max", float(storage_max(f16_ ? Storage::f16 : Storage::f32)));
    for (StageProgram* s : {extract_.get(), blur_.get(), composite_.get(), tonemap_.get(),
                            encode_.get()})
      s->set("range_guard", float(kRangeGuard));
    composite_->set("strength", p_.strength);
    tonemap_->set("exposure", p_.exposure);
    encode_->set("gamma", p_.gamma);
    if (p_.method == Method::mip) {
      down_ = std::make_unique<StageProgram>(ctx_, "downsample.glsl", defs, edit);
      up_ = std::make_unique<StageProgram>(ctx_, "upsample_tent.glsl", defs, edit);
      for (StageProgram* s : {down_.get(), up_.get()}) s->set("range_guard", float(kRangeGuard));
      down_->set_int("karis", p_.karis ? 1 : 0);
      down_->set("threshold", p_.threshold);
      down_->set("luma_gamma", p_.gamma);
    }
  }

  StageTrace run() {
    trace_.nonfinite = plan_.facts.nonfinite;
    raw_ = image(w_, h_, VK_FORMAT_R32G32B32A32_SFLOAT);
    std::vector<float> packed(std::size_t(w_) * h_ * kChannels);
    for (int y = 0; y < h_; ++y)
      std::copy(scene_.row(y), scene_.row(y) + std::size_t(w_) * kChannels,
                packed.begin() + std::size_t(y) * w_ * kChannels);
    raw_->upload(packed.data());
    for (auto* t : {&scene_img_, &bright_, &hdr_, &mapped_, &out_, &ping_[0], &ping_[1]})
      *t = image(w_, h_, format_);
    bloom_ = bright_.get();
    for (const StageSpec& s : plan_.stages) {
      const auto t0 = Clock::now();
      switch (s.kind) {
        case StageKind::input:
          device_ms_ = extract_->run({raw_.get()}, *scene_img_, bright_.get(), sampler_.handle());
          finish(s.name, *scene_img_, t0);
          break;
        case StageKind::bright:
          finish(s.name, *bright_, t0);
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
          device_ms_ = composite_->run({after() ? mapped_.get() : scene_img_.get(), bloom_}, *hdr_,
                                       nullptr, sampler_.handle());
          finish(s.name, *hdr_, t0);
          break;
        case StageKind::tonemap:
          device_ms_ = tonemap_->run({after() ? scene_img_.get() : hdr_.get()}, *mapped_, nullptr,
                                     sampler_.handle());
          finish(s.name, *mapped_, t0);
          break;
        case StageKind::output:
          device_ms_ = encode_->run({after() ? hdr_.get() : mapped_.get()}, *out_, nullptr,
                                    sampler_.handle());
          finish(s.name, *out_, t0);
          break;
      }
    }
    for (const auto& [name, ms] : trace_.timings) trace_.total_ms += ms;
    return std::move(trace_);
  }

 private:
  std::unique_ptr<Image2D> image(int w, int h, VkFormat f) {
    return std::make_unique<Image2D>(ctx_, w, h, f,
                                     VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_STORAGE_BIT);
  }

  // Method mip, after-tonemap (seed 003): the bloom is added to the tone-mapped scene.
  bool after() const {
    return p_.method == Method::mip && p_.composite == CompositeOrder::after_tonemap;
  }

  // A stage's wall time (its dispatch was submitted and waited for), then its image read back.
  // The device's time of the dispatch (device_ms_, -1: no timestamps; the bright stage is the
  // input's dispatch, timed there) goes to device_timings.
  void finish(const std::string& name, Image2D& img, Clock::time_point t0, bool skipped = false) {
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (!skipped) trace_.timings.emplace_back(name, ms);
    if (!skipped && device_ms_ >= 0) trace_.device_timings.emplace_back(name, device_ms_);
    device_ms_ = -1;
    trace_.stages.push_back({name, read(img), ms, skipped});
  }

  Image read(Image2D& img) {
    const std::vector<unsigned char> bytes = img.download();
    Image out = Image::uninitialised(img.width, img.height);
    const std::size_t n = std::size_t(img.width) * img.height * kChannels;
    if (img.format == VK_FORMAT_R32G32B32A32_SFLOAT) {
      std::memcpy(out.data(), bytes.data(), n * sizeof(float));
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        std::uint16_t bits = 0;
        std::memcpy(&bits, bytes.data() + 2 * i, 2);
        Imath::half h;
        h.setBits(bits);
        out.data()[i] = float(h);
      }
    }
    return out;
  }

  void blur(const StageSpec& s, Clock::time_point t0) {
    if (s.skipped) {  // the plan leaves it out: the bloom is what it was
      finish(s.name, *bloom_, t0, true);
      return;
    }
    Image2D& target = *ping_[s.pass % 2];
    if (!(faults_.skip_pass && s.pass == 3)) {
      blur_->set_int("horizontal", s.axis == Axis::horizontal ? 1 : 0);
      device_ms_ = blur_->run({bloom_}, target, nullptr, blur_sampler_.handle());
    }
    bloom_ = &target;
    finish(s.name, target, t0);
  }

  void levels() {
    if (!down_img_.empty()) return;
    for (std::size_t k = 0; k < plan_.levels.size(); ++k) {
      const int extra = faults_.level_size && k == 1 ? 1 : 0;
      const LevelSize& l = plan_.levels[k];
      down_img_.push_back(image(l.width + extra, l.height, format_));
      up_img_.push_back(image(l.width + extra, l.height, format_));
    }
    mip_bloom_ = image(w_, h_, format_);
  }

  void down(const StageSpec& s, Clock::time_point t0) {
    levels();
    const int k = s.pass;
    down_->set_int("first_level", k == 1 ? 1 : 0);
    device_ms_ = down_->run({k == 1 ? scene_img_.get() : down_img_[std::size_t(k - 2)].get()},
                            *down_img_[std::size_t(k - 1)], nullptr, sampler_.handle());
    finish(s.name, *down_img_[std::size_t(k - 1)], t0);
  }

  void up(const StageSpec& s, Clock::time_point t0) {
    const int k = s.pass, top = static_cast<int>(plan_.levels.size());
    // Level k + 1's result (the deepest level's downsample); with the fault, level 2 reads the
    // one after it.
    const int read = faults_.level_offset && k == 2 && top >= 4 ? k + 1 : k;
    const Image2D& small = read + 1 == top ? *down_img_[std::size_t(top - 1)] : *up_img_[std::size_t(read)];
    up_->set_int("has_current", 1);
    device_ms_ = up_->run({&small, down_img_[std::size_t(k - 1)].get()},
                          *up_img_[std::size_t(k - 1)], nullptr, sampler_.handle());
    finish(s.name, *up_img_[std::size_t(k - 1)], t0);
  }

  void mip_bloom(const StageSpec& s, Clock::time_point t0) {
    const Image2D& small = plan_.levels.size() == 1 ? *down_img_[0] : *up_img_[0];
    up_->set_int("has_current", 0);
    device_ms_ = up_->run({&small, &small}, *mip_bloom_, nullptr, sampler_.handle());
    bloom_ = mip_bloom_.get();
    finish(s.name, *mip_bloom_, t0);
  }

  Context::Impl& ctx_;
  const Plan& plan_;
  const BloomParams& p_;
  ConstImageView scene_;
  const int w_, h_;
  const HostFaults faults_;
  const bool f16_;
  const VkFormat format_;
  Sampler sampler_, blur_sampler_;
  std::unique_ptr<StageProgram> extract_, blur_, composite_, tonemap_, encode_, down_, up_;
  std::unique_ptr<Image2D> raw_, scene_img_, bright_, hdr_, mapped_, out_, ping_[2], mip_bloom_;
  std::vector<std::unique_ptr<Image2D>> down_img_, up_img_;
  Image2D* bloom_ = nullptr;
  double device_ms_ = -1;  // the last dispatch's time on the device, until finish takes it
  StageTrace trace_;
};

}  // namespace

StageTrace execute_vulkan(Context& ctx, const Plan& plan, ConstImageView scene,
                          const SourceEdit& edit, const HostFaults& faults) {
  const BloomParams& p = plan.params;
  if (p.precision != Precision::f32)
    throw ParamError("--precision f64 is the CPU truth; the Vulkan path computes in f32");
  if (p.mip_variant() || p.composite_mode != CompositeMode::add) {
    // A preset's chain: its host code as a description, each pass a compute shader.
    if (edit || faults.repeat_wrap || faults.skip_pass || faults.f16_storage ||
        faults.level_size || faults.level_offset)
      throw ParamError("faults are injected into bloomref's own pipeline shaders; a mip-chain "
                       "variant runs its preset's passes");
    return run_described(ctx, scene, gpu::preset_description(p, scene.width, scene.height), p);
  }
  if (p.storage != Storage::f32 && p.storage != Storage::f16)
    throw ParamError("--storage " + to_string(p.storage) + ": the Vulkan path's own pipeline "
                     "stores its stages as f32 or f16 (the GL path and the presets' passes take "
                     "every storage)");
  return VulkanExecutor(ctx, plan, scene, edit, faults).run();
}

}  // namespace bloomref::vulkan
