#version 330 core
// three.js's composite of its blurred mips (BloomNode.js, compositePass): each mip read with
// one lookup at the first mip's texel centre, times lerpBloomFactor of its factor (tints
// white), summed in order, times the strength. bloomref's own GLSL of it: `compare` runs it
// for preset threejs.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D blurTexture1;
uniform sampler2D blurTexture2;
uniform sampler2D blurTexture3;
uniform sampler2D blurTexture4;
uniform sampler2D blurTexture5;
uniform int mips;           // how many of the five are read
uniform vec4 bloomFactors;  // the first four mips' factors
uniform float bloomFactor5;
uniform float bloomRadius;
uniform float bloomStrength;

float lerpBloomFactor(float factor) {
  float mirrorFactor = 1.2 - factor;
  return mix(factor, mirrorFactor, bloomRadius);
}

void main() {
  vec3 sum = lerpBloomFactor(bloomFactors.x) * texture(blurTexture1, texCoord).rgb;
  if (mips > 1) sum = sum + lerpBloomFactor(bloomFactors.y) * texture(blurTexture2, texCoord).rgb;
  if (mips > 2) sum = sum + lerpBloomFactor(bloomFactors.z) * texture(blurTexture3, texCoord).rgb;
  if (mips > 3) sum = sum + lerpBloomFactor(bloomFactors.w) * texture(blurTexture4, texCoord).rgb;
  if (mips > 4) sum = sum + lerpBloomFactor(bloomFactor5) * texture(blurTexture5, texCoord).rgb;
  level = sum * bloomStrength;
}
