// bloomref — built-in scenes: procedural, deterministic, each with the case it exists for.
#pragma once

#include <string>
#include <vector>

#include "bloomref/image.h"

namespace bloomref {

struct SceneInfo {
  std::string name;
  std::string description;
  int width = 0, height = 0;  ///< default size
};

const std::vector<SceneInfo>& scene_list();

/// Builds a scene; width/height 0 take its default size. Throws ParamError for an unknown name
/// (listing the known ones) or a size the scene cannot have.
Image make_scene(const std::string& name, int width = 0, int height = 0);

}  // namespace bloomref
