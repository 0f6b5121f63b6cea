#version 450
// bloomref's compute downsample written to the interface of GraphicsSandbox's bloom
// (Itachi546/GraphicsSandbox at fddfdcf, GraphicsSandbox/Shaders/downsample.comp.glsl and
// Source/Engine/Pass/BloomPass.cpp): the level read at binding 0, the level written at binding
// 1, the written level's size in the push constants `width` and `height`. It computes
// bloomref's 13-tap downsample (seed 002; Jimenez 2014): taps one source texel apart around the
// target texel's centre, weights 1/8 (centre and inner four), 1/16 (edges), 1/32 (corners).
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D uInputTexture;
layout(binding = 1, rgba16f) uniform writeonly image2D uOutputTexture;

layout(push_constant) uniform PushConstant {
  float width;
  float height;
};

vec3 tap(vec2 uv, vec2 step, float x, float y) {
  return texture(uInputTexture, uv + vec2(x, y) * step).rgb;
}

void main() {
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= int(width) || texel.y >= int(height)) return;
  vec2 uv = (vec2(texel) + 0.5) / vec2(width, height);
  vec2 step = 1.0 / vec2(textureSize(uInputTexture, 0));
  vec3 sum = tap(uv, step, 0.0, 0.0) * 0.125;
  sum += (tap(uv, step, -1.0, -1.0) + tap(uv, step, 1.0, -1.0) +
          tap(uv, step, -1.0, 1.0) + tap(uv, step, 1.0, 1.0)) * 0.125;
  sum += (tap(uv, step, 0.0, -2.0) + tap(uv, step, -2.0, 0.0) +
          tap(uv, step, 2.0, 0.0) + tap(uv, step, 0.0, 2.0)) * 0.0625;
  sum += (tap(uv, step, -2.0, -2.0) + tap(uv, step, 2.0, -2.0) +
          tap(uv, step, -2.0, 2.0) + tap(uv, step, 2.0, 2.0)) * 0.03125;
  imageStore(uOutputTexture, texel, vec4(sum, 1.0));
}
