// bloomref describe --preset P --size WxH -o P.json: a preset's host code as a pipeline
// description (docs/check.md, "Any host code"), with bloomref's shaders of its passes beside it,
// to start a description of one's own host code from.
#include <filesystem>
#include <iostream>
#include <memory>

#include "bloomref/error.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/output_files.h"
#include "check/pipeline.h"
#include "commands.h"
#include "options.h"

namespace bloomref::cli {

std::function<int()> add_describe(CLI::App& app) {
  struct Args {
    std::string output, size;
    PipelineOptions pipeline;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand(
      "describe", "write a preset's host code as a pipeline description, its shaders beside it");
  sub->add_option("-o,--output", a->output, "the description, FILE.json (its shaders go to FILE/)")
      ->required();
  a->pipeline.add_to(*sub);
  return [a, sub]() -> int {
    if (!sub->parsed()) return -1;
    a->pipeline.finish();
    const BloomParams& p = a->pipeline.params;
    if (!(p.mip_variant() || p.composite_mode != CompositeMode::add))
      throw ParamError("describe writes a mip-chain preset's host code (--preset "
                       "learnopengl-pbb, bevy, bevy-old-school, unity-urp or their overrides); "
                       "bloomref's own pipeline runs without host code of its own");
    std::string source;
    const LoadedImage scene = a->pipeline.load_input("", source);  // --scene/--size: the size
    const gpu::PipelineDescription d =
        gpu::preset_description(p, scene.image.width(), scene.image.height());
    const std::string size = std::to_string(scene.image.width()) + "x" +
                             std::to_string(scene.image.height());
    // The preset named (bevy-old-school draws Bevy's layout), else the layout's.
    const std::string what = a->pipeline.preset.empty() ? d.file : "preset " + a->pipeline.preset;
    const auto files = pipeline_files(
        d, a->output, "bloomref's " + what + " for a " + size + " scene",
        "bloomref describe: gpu::preset_description, its textures sized for " + size +
            " (docs/presets.md cites the code each preset follows)");
    OutputSet outs;
    for (std::size_t i = 0; i < files.size(); ++i) {
      if (i == 1) outs.add_folder(std::filesystem::path(files[i].first).parent_path().string(),
                                  "--output's shader folder", false);
      outs.add_file(files[i].first, i == 0 ? "--output" : "--output's shaders");
    }
    for (const auto& [path, text] : files) outs.write_text(path, text);
    outs.publish();  // all of them, or none
    std::cout << "wrote " << a->output << " and " << files.size() - 1 << " shader(s) for "
              << what << " at " << size << "\n";
    return 0;
  };
}

}  // namespace bloomref::cli
