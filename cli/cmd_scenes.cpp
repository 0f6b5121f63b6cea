// bloomref scenes [NAME] -o OUT.exr : list or write the built-in scenes.
#include <iomanip>
#include <iostream>
#include <memory>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"
#include "commands.h"
#include "options.h"

namespace bloomref::cli {

std::function<int()> add_scenes(CLI::App& app) {
  struct Args {
    std::string name, output, size;
  };
  auto args = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand("scenes", "list the built-in scenes, or write one");
  sub->add_option("NAME", args->name, "scene to write");
  sub->add_option("-o,--output", args->output, "OUT.exr (or .png)");
  sub->add_option("--size", args->size, "WxH (default: the scene's own)");
  return [args, sub]() -> int {
    if (!sub->parsed()) return -1;
    if (args->name.empty()) {
      for (const SceneInfo& s : scene_list())
        std::cout << std::left << std::setw(15) << s.name << std::setw(11)
                  << (std::to_string(s.width) + "x" + std::to_string(s.height)) << s.description
                  << "\n";
      return 0;
    }
    if (args->output.empty()) throw ParamError("give -o OUT.exr to write scene '" + args->name + "'");
    int w = 0, h = 0;
    if (!args->size.empty()) parse_size(args->size, w, h);
    const Image img = make_scene(args->name, w, h);
    save_image(args->output, img.cview());
    std::cout << "wrote " << args->output << " (" << img.width() << "x" << img.height() << ")\n";
    return 0;
  };
}

}  // namespace bloomref::cli
