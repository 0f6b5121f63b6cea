#version 450
// bloomref's compute upsample written to the interface of GraphicsSandbox's bloom
// (Itachi546/GraphicsSandbox at fddfdcf, GraphicsSandbox/Shaders/upsample.comp.glsl): the
// smaller level read at binding 0, the larger level at binding 1 read and written in place,
// its size in `width` and `height`, the tent's step `radius` in its texels (2: one texel of
// the smaller level where sizes halve exactly). It computes bloomref's upsample (seed 002): the
// level plus the 3x3 tent (1 2 1 / 2 4 2 / 1 2 1, over 16) of the smaller level.
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D uInputTexture;
layout(binding = 1, rgba16f) uniform image2D uOutputTexture;

layout(push_constant) uniform PushConstant {
  float width;
  float height;
  float radius;
};

vec3 tap(vec2 uv, vec2 step, float x, float y) {
  return texture(uInputTexture, uv + vec2(x, y) * step).rgb;
}

void main() {
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= int(width) || texel.y >= int(height)) return;
  vec2 uv = (vec2(texel) + 0.5) / vec2(width, height);
  vec2 step = radius / vec2(width, height);
  vec3 tent = tap(uv, step, 0.0, 0.0) * 4.0;
  tent += (tap(uv, step, 0.0, -1.0) + tap(uv, step, -1.0, 0.0) +
           tap(uv, step, 1.0, 0.0) + tap(uv, step, 0.0, 1.0)) * 2.0;
  tent += tap(uv, step, -1.0, -1.0) + tap(uv, step, 1.0, -1.0) +
          tap(uv, step, -1.0, 1.0) + tap(uv, step, 1.0, 1.0);
  vec3 level = imageLoad(uOutputTexture, texel).rgb;
  imageStore(uOutputTexture, texel, vec4(level + tent * (1.0 / 16.0), 1.0));
}
