// bloomref — a Plan: the ordered, named stages to run for these parameters and this scene.
//
// Stage names are stable (code, files, JSON, CLI): gaussian: input, bright, blur.1 .. blur.N,
// composite, tonemap, output; mip: input, down.1 .. down.K, up.K-1 .. up.1, bloom, then
// composite, tonemap, output (before-tonemap) or tonemap, composite, output (after-tonemap). The adaptive plan leaves out work the scene does not need and gives the same
// bits as the full plan:
//  * no NaN/Inf in the input -> no sanitising (the input stage only copies and stores);
//  * nothing above the threshold -> no blur passes: the blur of an all-zero bright image is
//    exactly zero (every tap multiplies 0), so the bloom is the bright image itself.
#pragma once

#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/mip.h"
#include "bloomref/params.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref {

enum class StageKind { input, bright, blur, down, up, bloom, composite, tonemap, output };

struct StageSpec {
  std::string name;
  StageKind kind = StageKind::input;
  int pass = 0;                     ///< blur pass number, 1-based; mip level of down.k / up.k
  Axis axis = Axis::horizontal;     ///< blur passes only
  bool skipped = false;             ///< left out by the adaptive plan (result known exactly)
};

/// What the plan learned from one scan of the scene.
struct SceneFacts {
  int width = 0, height = 0;
  NonFiniteCounts nonfinite;
  std::uint64_t bright_pixels = 0;  ///< luminance > threshold after the policy
  /// Per row: 1 where the row holds a bright pixel, else 0 (the input stage of the adaptive
  /// plan reads only those rows of a sparse scene).
  std::vector<std::uint8_t> bright_rows;
  /// How long the scan took: the executors report it as the first timing, "plan", and count
  /// it in their total (a plan is made for one run: what it learned is the scene's).
  double scan_ms = 0;
};

struct Plan {
  BloomParams params;
  SceneFacts facts;
  std::vector<StageSpec> stages;
  bool sanitize = true;  ///< input stage applies the non-finite policy
  /// Adaptive gaussian plan: the scene is dense (dense_scene): where the fused f32 blur runs,
  /// the adaptive plan blurs it as the full plan does, without tracking a support.
  bool dense_scene = false;
  /// Adaptive gaussian plan: the scene is small (small_scene): blurred as a dense one is.
  bool small_scene = false;
  std::vector<LevelSize> levels;  ///< method mip: sizes of levels 1..K actually used
  std::vector<std::string> skipped_names() const;
};

/// Validates the parameters, scans the scene and builds the plan. Throws ParamError for bad
/// parameters and InputError (naming `source`) when the policy is `error` and the scene holds
/// NaN or Inf, or the scene is empty. A scene of at most 128x128 pixels whose thread count is
/// left to bloomref (params.threads 0) is planned (and scanned) on one thread.
Plan make_plan(const BloomParams& params, ConstImageView scene, const std::string& source = "");

/// The plan's scan of the scene alone (make_plan's first step), its row kernel `isa`'s
/// (BlurIsa::best: the widest this CPU has; ParamError for one it lacks): the same facts from
/// every kernel.
SceneFacts scan_scene(ConstImageView scene, const BloomParams& params, BlurIsa isa = BlurIsa::best);
/// Whether the bright pixels are so many and so spread that tracking the blur's support costs
/// more than it saves: at least 10% of the pixels bright, on at least half the rows. The
/// corpus's scenes this takes run faster under the full plan, and those it leaves (compact
/// ones) faster tracked (docs/design.md, "A scene bright on half its rows is blurred whole").
bool dense_scene(const SceneFacts& facts);
/// Whether the scene is so small (at most 256x256 pixels) that following its support costs
/// more than it leaves out, however sparse it is: its fixed costs (the support's spans, the
/// boxes, the finishing table) are a run's whole length there (docs/design.md, "A small scene
/// is blurred whole").
bool small_scene(const SceneFacts& facts);

/// How a stage's output is stored: the mip chain's levels (down.k, up.k) as the chain stores
/// them (BloomParams::level_storage), every other stage as `storage` says.
inline Storage stage_storage(const BloomParams& p, StageKind kind) {
  return kind == StageKind::down || kind == StageKind::up ? p.level_storage() : p.storage;
}
inline Storage stage_storage(const BloomParams& p, const StageSpec& s) {
  return stage_storage(p, s.kind);
}

/// The stage whose image is the bloom the composite adds: `bloom` (mip), the last blur pass, or
/// `bright` when there are no passes.
std::string bloom_stage_name(const Plan& plan);

/// The stage names of the full plan for these parameters and image size.
std::vector<std::string> stage_names(const BloomParams& params, int width, int height);

}  // namespace bloomref
