#version 330 core
// three.js's luminosity high pass (mrdoob/three.js examples/jsm/tsl/display/BloomNode.js,
// luminosityHighPass; docs/presets.md): one lookup of the scene at the half-size texel's
// centre, times smoothstep(threshold, threshold + smoothWidth, its luminance). bloomref's own
// GLSL of it: `compare` runs it for preset threejs.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform float threshold;
uniform float smoothWidth;
uniform vec3 lumaWeights;  // the luminance's weights (three.js's: Rec. 709)

void main() {
  vec4 texel = texture(srcTexture, texCoord);
  float v = dot(texel.rgb, lumaWeights);
  float alpha = smoothstep(threshold, threshold + smoothWidth, v);
  level = mix(vec4(0.0), texel, alpha).rgb;
}
