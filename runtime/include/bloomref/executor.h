// bloomref — the CPU executor: runs a Plan on a scene and returns its StageTrace.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/plan.h"

namespace bloomref {

struct StageResult {
  std::string name;
  Image image;      ///< as stored (f16 values when storage is f16); f64 runs are shown in float
  double ms = 0;    ///< wall time of the stage, including its storage rounding
  bool skipped = false;
};

struct StageTrace {
  std::vector<StageResult> stages;  ///< every stage when keep_all, else only `output`
  NonFiniteCounts nonfinite;        ///< what the input stage found
  double total_ms = 0;
  std::optional<ImageF64> output_f64;  ///< the output stage in double (f64 precision only)
  std::vector<std::pair<std::string, double>> timings;  ///< every stage that ran, in order
  /// Each stage's time on the device, from its timer queries (GL_TIME_ELAPSED around the
  /// stage's draws, Vulkan timestamps around its dispatch): no drain or readback in it. Empty on
  /// the CPU and where the device has no timer.
  std::vector<std::pair<std::string, double>> device_timings;
  /// Adaptive plan: per blur pass, the fraction of texels left out (outside the bright pixels'
  /// dilated support, where the blur is exactly 0); for composite+tonemap+output, where it
  /// used one, the fraction of pixels finished from the table of binary16 values (stages.h:
  /// finish_fast) instead of computed.
  std::vector<std::pair<std::string, double>> skipped_fraction;

  const Image& final_image() const { return stages.back().image; }
  const StageResult* find(const std::string& name) const;
};

struct ExecuteOptions {
  bool keep_all = false;  ///< keep every intermediate (compare, debug, --dump-stages)
  /// How f16 storage rounds: nearest-even, finite values saturating at 65504 (a finite input
  /// never turns into Inf through storage, so no +Inf and -Inf meet in a later sum: measured on
  /// WideFloatRange.exr, IEEE overflow gave 478134 NaN in the mip chain). `compare` uses the
  /// device's measured mode.
  HalfRounding half_rounding = HalfRounding::nearest_even_saturate;
};

/// Runs `plan` on `scene`, which must stay unchanged until it returns: where no stage writes the
/// scene before the finishing stages (f32, gaussian, no NaN or Inf to sanitise, the finish fused)
/// it is read in place, otherwise copied first.
StageTrace execute(const Plan& plan, ConstImageView scene, const ExecuteOptions& opt = {});

/// The same, taking the scene over (f32): its buffer becomes the input stage's, saving a copy
/// (peak memory of `run`: the scene, two blur buffers and the masks). `scene` is left empty.
StageTrace execute(const Plan& plan, Image&& scene, const ExecuteOptions& opt = {});

/// The same, reading `scene` where the first overload reads it, and writing the output into
/// `output`'s buffer (taken over, left empty) when it has the scene's size, else into a new one:
/// for a caller that keeps its scene and runs again at one size (the Python module hands back
/// the buffer of an output it has released). A buffer whose pages are already mapped saves
/// their faults on its first write (docs/design.md, "Nothing is written where nothing is").
StageTrace execute(const Plan& plan, ConstImageView scene, Image&& output,
                   const ExecuteOptions& opt = {});

/// Whether the second and third overloads leave the output in the buffer they were handed (the
/// scene's; the output's when it has the scene's size) rather than in a new one: in f32 under
/// the gaussian method, where every stage after the input writes that buffer in place, when no
/// intermediate is kept (tested for every plan, blur and storage). The Python module hands an
/// array's own buffer to the executor (`out=`) only then.
bool output_in_given_buffer(const BloomParams& params, const ExecuteOptions& opt);

/// The adaptive plan keeps the two zeroed scratch images of its last sparse runs (at most two,
/// each the size of the scene) so that the next run of that size does not zero or fault in a
/// whole image again; this frees them.
void release_scratch_images();

}  // namespace bloomref
