#version 330 core
// One level of the mip chain's downsample with the interface of LearnOpenGL's "Physically Based
// Bloom" host code (docs/check.md, "A mip-chain bloom"): 13 bilinear taps at 0, +-1 and +-2
// steps of 1 / srcResolution; on mipLevel 0 each group of four taps is weighted by
// 1 / (1 + luma / 4), luma the Rec. 601 weights of the group encoded with gamma 1 / 2.2, and the
// sum kept at least 0.0001 (docs/design.md, "Mip-chain variants"). bloomref's own: `compare`
// runs it for preset learnopengl-pbb, and the bug corpus (data/bugs/) changes it.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform vec2 srcResolution;
uniform int mipLevel = 1;

vec3 tap(vec2 steps) {
  return texture(srcTexture, texCoord + steps / srcResolution).rgb;
}

vec3 weighted(vec3 group) {
  vec3 encoded = pow(group, vec3(1.0 / 2.2));
  return group / (1.0 + 0.25 * dot(encoded, vec3(0.299, 0.587, 0.114)));
}

void main() {
  vec3 c = tap(vec2(0.0));
  vec3 n = tap(vec2(0.0, 2.0)), s = tap(vec2(0.0, -2.0));
  vec3 e = tap(vec2(2.0, 0.0)), w = tap(vec2(-2.0, 0.0));
  vec3 ne = tap(vec2(2.0, 2.0)), nw = tap(vec2(-2.0, 2.0));
  vec3 se = tap(vec2(2.0, -2.0)), sw = tap(vec2(-2.0, -2.0));
  vec3 i0 = tap(vec2(-1.0, 1.0)), i1 = tap(vec2(1.0, 1.0));
  vec3 i2 = tap(vec2(-1.0, -1.0)), i3 = tap(vec2(1.0, -1.0));
  if (mipLevel == 0) {
    vec3 sum = weighted((nw + n + w + c) * 0.03125) + weighted((n + ne + c + e) * 0.03125) +
               weighted((w + c + sw + s) * 0.03125) + weighted((c + e + s + se) * 0.03125) +
               weighted((i0 + i1 + i2 + i3) * 0.125);
    level = max(sum, vec3(0.0001));
  } else {
    level = c * 0.125 + (nw + ne + sw + se) * 0.03125 + (n + s + e + w) * 0.0625 +
            (i0 + i1 + i2 + i3) * 0.125;
  }
}
