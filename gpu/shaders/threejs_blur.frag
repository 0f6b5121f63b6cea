#version 330 core
// One pass of three.js's separable blur (BloomNode.js, _getSeparableBlurMaterial): the centre
// times c_0, then each pair at +-i texels of the target along `direction` times c_i, i below
// the kernel's radius, not normalised. The coefficients are the host's, rounded to float as
// its uniform array holds them. bloomref's own GLSL of it: `compare` runs it for preset threejs.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D colorTexture;
uniform vec2 invSize;    // 1 / the target's size
uniform vec2 direction;  // (1, 0) or (0, 1)
uniform int kernelRadius;
// c_0 .. c_23 (a description sets vectors of at most four floats).
uniform vec4 coefficients0;
uniform vec4 coefficients1;
uniform vec4 coefficients2;
uniform vec4 coefficients3;
uniform vec4 coefficients4;
uniform vec4 coefficients5;

float coefficient(int i) {
  vec4 c = i < 4    ? coefficients0
           : i < 8  ? coefficients1
           : i < 12 ? coefficients2
           : i < 16 ? coefficients3
           : i < 20 ? coefficients4
                    : coefficients5;
  return c[i % 4];
}

void main() {
  vec3 diffuseSum = texture(colorTexture, texCoord).rgb * coefficient(0);
  for (int i = 1; i < kernelRadius; i++) {
    float x = float(i);
    float w = coefficient(i);
    vec2 uvOffset = direction * invSize * x;
    vec3 sample1 = texture(colorTexture, texCoord + uvOffset).rgb;
    vec3 sample2 = texture(colorTexture, texCoord - uvOffset).rgb;
    diffuseSum += (sample1 + sample2) * w;
  }
  level = diffuseSum;
}
