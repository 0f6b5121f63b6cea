// bloomref bench --pass-probe: where a GPU's time goes, one 9-tap pass at a time.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "bloomref/gpu/context.h"
#include "bloomref/params.h"
#include "bloomref/vulkan/context.h"

namespace bloomref::cli {

/// Times one 9-tap blur pass (blur.1 of a one-pass gaussian plan) on a `width` x `height`
/// `scene_name` scene, `repeat` times after a warm-up, as a GL fragment pass and a GL compute
/// pass (`gl`, when not null) and a Vulkan compute dispatch (`vk`, when not null): the medians
/// of the stage's wall time and of its device time (GL's timer queries, Vulkan's timestamps;
/// absent where the device gives none), the effective traffic of one read and one write of the
/// image at the storage's texel size, and the device's SMs or compute units where Vulkan
/// reports them. Each backend's blur.1 is checked against the CPU's (largest difference within
/// 1e-3 of the value's magnitude). Prints a table; returns it as JSON.
nlohmann::ordered_json pass_probe(const BloomParams& params, const std::string& scene_name,
                                  int width, int height, int repeat, gpu::GlContext* gl,
                                  vulkan::Context* vk, bool& all_checked);

}  // namespace bloomref::cli
