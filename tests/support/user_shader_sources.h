// Shaders written for the tests from docs/design.md ("Specification"), with the interface of the learnopengl preset
// (gpu/user_pipeline.h): the tutorial's names, written independently of its files.
#pragma once

#include <string>

#include "bloomref/gpu/user_pipeline.h"

namespace bloomref::test {

// discrete9 written from docs/design.md ("Specification", stage 3): a centre tap and four pairs at i texels,
// weights 924, 792, 495, 220, 66 over 4070, added centre first, then +i before -i.
inline const char* kBlur9 = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D image;
uniform bool horizontal;
uniform float w[5] = float[](0.2270270270, 0.1945945946, 0.1216216216, 0.0540540541,
                             0.0162162162);
void main() {
  vec2 texel = 1.0 / vec2(textureSize(image, 0));
  vec2 d = horizontal ? vec2(texel.x, 0.0) : vec2(0.0, texel.y);
  vec3 sum = texture(image, TexCoords).rgb * w[0];
  for (int i = 1; i < 5; ++i) {
    sum += texture(image, TexCoords + d * float(i)).rgb * w[i];
    sum += texture(image, TexCoords - d * float(i)).rgb * w[i];
  }
  colour = vec4(sum, 1.0);
}
)glsl";

// docs/design.md ("Specification") stages 4-6 in one pass (strength 1, gamma 2.2), as the tutorial's final pass does.
inline const char* kFinal = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform bool bloom;
uniform float exposure;
void main() {
  vec3 hdr = texture(scene, TexCoords).rgb;
  if (bloom) hdr += texture(bloomBlur, TexCoords).rgb;
  vec3 mapped = 1.0 - exp(-hdr * exposure);
  colour = vec4(pow(max(mapped, 0.0), vec3(1.0 / 2.2)), 1.0);
}
)glsl";

// A bright pass written from docs/design.md ("Specification") stage 2 (Rec. 709 luminance, strictly above the
// threshold), reading the scene with texture() at TexCoords as a user writes it.
inline const char* kBright = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 bright;
uniform sampler2D scene;
uniform float threshold;
void main() {
  vec3 c = texture(scene, TexCoords).rgb;
  float l = dot(c, vec3(0.2126, 0.7152, 0.0722));
  bright = l > threshold ? vec4(c, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
)glsl";

/// The shaders above, or others in their place, named as files would be in errors.
inline gpu::LearnOpenGLShaders own_shaders(const std::string& blur = kBlur9,
                                           const std::string& final_fs = kFinal) {
  gpu::LearnOpenGLShaders s;
  s.blur_fs = {"test_blur9.fs", blur};
  s.final_fs = {"test_final.fs", final_fs};
  return s;
}

}  // namespace bloomref::test
