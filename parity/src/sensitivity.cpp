// What a check could have seen (compare.h, Sensitivity): a wrong bloom planted in the oracle's
// run, its images handed to the same comparison as captures, judged.
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>

#include "bloomref/engine/fast_stages.h"
#include "bloomref/error.h"
#include "bloomref/parity/compare.h"
#include "chain.h"
#include "stage_terms.h"

namespace bloomref::parity {

using namespace detail;

namespace {

// The first stage of the bloom: the one whose change the rest of the bloom carries.
const StageSpec* first_bloom_stage(const Plan& plan) {
  for (const StageSpec& s : plan.stages)
    if (s.kind == StageKind::blur || s.kind == StageKind::down) return &s;
  return nullptr;
}

const StageSpec* stage_named(const Plan& plan, const std::string& name) {
  for (const StageSpec& s : plan.stages)
    if (s.name == name) return &s;
  throw ParamError("no stage '" + name + "' to plant a change in");
}

// A discrete kernel on texel offsets 0..4 (taps on centres, as discrete9's), Gaussian with
// `sigma`, normalised: the blur of a bloom whose spread is not the specified one.
Kernel gaussian_kernel(double sigma) {
  Kernel k;
  k.name = "planted";
  double total = 0;
  std::vector<double> w;
  for (int i = 0; i <= 4; ++i) {
    w.push_back(std::exp(-0.5 * i * i / (sigma * sigma)));
    total += i == 0 ? w.back() : 2 * w.back();
  }
  for (int i = 0; i <= 4; ++i) {
    k.offsets_f64.push_back(i);
    k.offsets_f32.push_back(static_cast<float>(i));
    k.weights_f64.push_back(w[std::size_t(i)] / total);
    k.weights_f32.push_back(static_cast<float>(w[std::size_t(i)] / total));
  }
  return k;
}

// The standard deviation of one pass of a kernel, in texels.
double kernel_sigma(const Kernel& k) {
  double var = 0;
  for (std::size_t i = 1; i < k.weights_f64.size(); ++i)
    var += 2 * k.weights_f64[i] * k.offsets_f64[i] * k.offsets_f64[i];
  return std::sqrt(var);
}

double srgb_to_linear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}
double linear_to_srgb(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}

// The oracle's run with one change planted, stage by stage in plan order; each stage's image
// is kept until no later stage reads it.
class PlantedRun {
 public:
  PlantedRun(const Plan& plan, ConstImageView scene, const DeviceProfile& profile,
             const PlantedChange& change, const std::map<std::string, int>& codes)
      : plan_(plan), profile_(profile), change_(change), codes_(codes),
        at_(change.stage.empty() ? first_bloom_stage(plan) : stage_named(plan, change.stage)) {
    const BloomParams& p = plan.params;
    sanitized_ = Image::uninitialised(scene.width, scene.height);
    sanitize(scene, sanitized_.view(), p.nonfinite, p.storage, p.threads);
    for (std::size_t i = 0; i < plan.stages.size(); ++i)
      for (const std::string& in : stage_inputs(plan, plan.stages[i])) last_read_[in] = i;
    if (change.kind == PlantedChange::spread)
      wider_ = gaussian_kernel(kernel_sigma(kernel_for(p.kernel)) * change.amount);
  }

  OwnedCapture capture(const std::string& stage) {
    while (done_ < plan_.stages.size() && !held_.count(stage)) step();
    const Image& img = held_.at(stage);
    OwnedCapture out{Image::uninitialised(img.width(), img.height()), 0, false};
    std::copy(img.values().begin(), img.values().end(), out.image.data());
    const auto c = codes_.find(stage);
    if (c != codes_.end() && c->second != 0) quantise(out.image, c->second < 0);
    out.code_bits = c != codes_.end() ? std::abs(c->second) : 0;
    out.srgb = c != codes_.end() && c->second < 0;
    return out;
  }

 private:
  void step() {
    const StageSpec& spec = plan_.stages[done_];
    const BloomParams& p = plan_.params;
    std::vector<ConstImageView> in;
    for (const std::string& n : stage_inputs(plan_, spec)) in.push_back(held_.at(n).cview());
    Image out;
    const bool widened = change_.stage.empty() ? spec.kind == StageKind::blur : &spec == at_;
    if (change_.kind == PlantedChange::spread && widened) {
      out = Image::uninitialised(in[0].width, in[0].height);
      blur_pass_fast(in[0], out.view(), {spec.axis, &wider_, profile_.subtexel_bits}, p.threads);
    } else {
      out = oracle_stage(plan_, spec, sanitized_.cview(), in, profile_.subtexel_bits, pool_);
    }
    if (&spec == at_) plant(out);
    store(out.view(), stage_storage(p, spec), half_rounding_for(profile_), p.threads);
    held_[spec.name] = std::move(out);
    // Images no later stage reads are dropped once handed out (capture copies them).
    for (auto it = held_.begin(); it != held_.end();) {
      const auto r = last_read_.find(it->first);
      const bool read_later = r != last_read_.end() && r->second > done_;
      it = !read_later && it->first != spec.name ? held_.erase(it) : std::next(it);
    }
    ++done_;
  }

  void plant(Image& img) const {
    if (change_.kind == PlantedChange::gain) {
      for (float& v : img.values()) v = static_cast<float>(v * change_.amount);
    } else if (change_.kind == PlantedChange::shift) {
      // Moved `amount` texels right (clamp-to-edge at the left).
      const int s = static_cast<int>(change_.amount), w = img.width();
      std::vector<float> row(std::size_t(w) * kChannels);
      for (int y = 0; y < img.height(); ++y) {
        float* r = img.pixel(0, y);
        for (int x = 0; x < w; ++x)
          std::copy_n(r + std::size_t(std::clamp(x - s, 0, w - 1)) * kChannels, kChannels,
                      &row[std::size_t(x) * kChannels]);
        std::copy(row.begin(), row.end(), r);
      }
    }
  }

  // As an 8-bit capture holds it: clamped to [0, 1], rounded to codes (sRGB-encoded or not).
  static void quantise(Image& img, bool srgb) {
    float* d = img.data();
    for (std::size_t i = 0; i < img.values().size(); ++i) {
      if (i % kChannels == 3) continue;
      double v = std::clamp(static_cast<double>(d[i]), 0.0, 1.0);
      if (std::isnan(d[i])) v = 0;
      v = srgb ? srgb_to_linear(std::round(linear_to_srgb(v) * 255) / 255)
               : std::round(v * 255) / 255;
      d[i] = static_cast<float>(v);
    }
  }

  const Plan& plan_;
  const DeviceProfile& profile_;
  PlantedChange change_;
  const std::map<std::string, int>& codes_;
  const StageSpec* at_;  // where the change enters
  Image sanitized_;
  Kernel wider_;
  ImagePool pool_;
  std::map<std::string, Image> held_;
  std::map<std::string, std::size_t> last_read_;
  std::size_t done_ = 0;
};

// Whether the captures of `names`, made by the oracle with `change` planted, fail.
bool planted_fails(const Plan& plan, ConstImageView scene, const std::vector<std::string>& names,
                   const std::map<std::string, int>& codes, const DeviceProfile& profile,
                   const PlantedChange& change, CompareOptions opt, std::string& stage) {
  PlantedRun run(plan, scene, profile, change, codes);
  opt.causes = false;
  opt.keep_images = false;
  opt.worst_count = 0;
  opt.stop_at_first_fail = true;
  const ParityResult r = compare_streamed(
      plan, scene, names, [&run](const std::string& n) { return run.capture(n); }, profile, opt);
  for (std::size_t i = 0; i < r.isolated.size(); ++i)
    if (r.isolated[i].verdict == Verdict::fail || r.end_to_end[i].verdict == Verdict::fail) {
      stage = r.isolated[i].stage + (r.isolated[i].verdict == Verdict::fail ? "" : " (end to end)");
      return true;
    }
  return false;
}

// The smallest amount of `ladder` (ascending) whose change fails, on the assumption that a
// larger change fails whenever a smaller one does (what the planted tests check): the amount
// at `start` first (the one that decides a weak verdict), then halving the rest of the ladder
// on its side. 0 when none does.
double smallest_failing(const std::vector<double>& ladder, std::size_t start, PlantedChange::Kind kind,
                        const std::function<bool(const PlantedChange&, std::string&)>& fails,
                        std::string& stage, bool below = true) {
  std::size_t lo = below ? 0 : std::min(start, ladder.size() - 1), hi = ladder.size();  // fails at hi (ladder.size(): not known to)
  std::string at;
  std::size_t mid = std::min(start, ladder.size() - 1);
  while (lo < hi) {
    std::string s;
    if (fails({kind, ladder[mid], {}}, s)) {
      hi = mid;
      at = s;
    } else {
      lo = mid + 1;
    }
    mid = (lo + hi) / 2;
  }
  stage = at;
  return hi < ladder.size() ? ladder[hi] : 0.0;
}

}  // namespace

Sensitivity sensitivity(const Plan& plan, ConstImageView scene,
                        const std::vector<std::string>& captured,
                        const std::map<std::string, int>& codes, const DeviceProfile& profile,
                        const CompareOptions& opt, double required_gain, bool shape,
                        bool per_stage) {
  Sensitivity s;
  if (!first_bloom_stage(plan)) return s;
  auto fails = [&](const PlantedChange& c, std::string& stage) {
    return planted_fails(plan, scene, captured, codes, profile, c, opt, stage);
  };
  const std::vector<double>& gains = Sensitivity::gain_ladder();
  const std::size_t start = static_cast<std::size_t>(
      std::lower_bound(gains.begin(), gains.end(), required_gain * (1 - 1e-9)) - gains.begin());
  // Without `shape`, a gain the floor already fails is stated as "at most" the floor: one run.
  s.gain = smallest_failing(gains, start, PlantedChange::gain, fails, s.gain_stage, shape);
  s.gain_at_most = !shape && s.gain > 0 && start > 0 && s.gain == gains[std::min(start, gains.size() - 1)];
  if (!shape) return s;
  s.shift = smallest_failing(Sensitivity::shift_ladder(), 0, PlantedChange::shift, fails, s.shift_stage);
  if (plan.params.method == Method::gaussian) {
    s.spread = smallest_failing(Sensitivity::spread_ladder(), 2, PlantedChange::spread, fails,
                                s.spread_stage);
    s.spread_measured = true;
  }
  s.shape = true;
  if (!per_stage) return s;
  const std::size_t gain_start = std::min(start, gains.size() - 1);
  for (const std::string& name : captured) {
    StageSensitivity st;
    st.stage = name;
    auto at = [&](const PlantedChange& c, std::string& stage) {
      PlantedChange here = c;
      here.stage = name;
      return fails(here, stage);
    };
    st.gain = smallest_failing(gains, gain_start, PlantedChange::gain, at, st.gain_stage);
    st.shift = smallest_failing(Sensitivity::shift_ladder(), 0, PlantedChange::shift, at, st.shift_stage);
    if (plan.params.method == Method::gaussian && stage_named(plan, name)->kind == StageKind::blur) {
      st.spread = smallest_failing(Sensitivity::spread_ladder(), 2, PlantedChange::spread, at,
                                   st.spread_stage);
      st.spread_measured = true;
    }
    s.stages.push_back(std::move(st));
  }
  return s;
}

const std::vector<double>& Sensitivity::gain_ladder() {
  static const std::vector<double> l{1.01, 1.02, 1.05, 1.1, 1.2, 1.5, 2.0, 4.0};
  return l;
}
const std::vector<double>& Sensitivity::shift_ladder() {
  static const std::vector<double> l{1, 2, 4, 8};
  return l;
}
const std::vector<double>& Sensitivity::spread_ladder() {
  static const std::vector<double> l{1.02, 1.05, 1.1, 1.2, 1.5};
  return l;
}

}  // namespace bloomref::parity
