#version 450
// Device-facts probe for Vulkan (vulkan/src/device_facts.cpp), the compute twin of
// gpu/shaders/probe.glsl: mode 0 copies texels into the storage image (how a store rounds),
// mode 1 samples with the linear sampler at u = (x / 1024) * 0.5 + 0.25 between the two texels
// of a 2-texel row (weight precision), mode 2 evaluates a * b + c (FMA contraction) and v * 0.5
// (denormal flush) from the push constants. STORAGE is the image's format (rgba32f or rgba16f).
layout(local_size_x = 64) in;
layout(binding = 0) uniform sampler2D src;
layout(binding = 1, STORAGE) uniform writeonly image2D dst;
layout(push_constant) uniform Probe {
  int mode;
  float a, b, c, v;
} probe;

void main() {
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= imageSize(dst).x) return;
  vec4 r;
  if (probe.mode == 0) {
    r = texelFetch(src, texel, 0);
  } else if (probe.mode == 1) {
    float s = ((float(texel.x) + 0.5) / 1024.0) * 0.5 + 0.25;
    r = texture(src, vec2(s, 0.5));
  } else {
    r = vec4(probe.a * probe.b + probe.c, probe.v * 0.5, 0.0, 1.0);
  }
  imageStore(dst, texel, r);
}
