#version 330 core
// The first level of Unity URP's bloom (Unity-Technologies/Graphics,
// com.unity.render-pipelines.universal/Shaders/PostProcessing/Bloom.shader, FragPrefilter;
// docs/presets.md): one bilinear lookup at the half-size texel's centre, min(clamp, colour),
// then the soft threshold in the shader's own arithmetic. bloomref's own GLSL of it: `compare`
// runs it for preset unity-urp.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
// URP's _Params: scatter, clamp, threshold (linear), threshold knee.
uniform vec4 params;
uniform int softThreshold;  // 1: the soft threshold (--prefilter soft-knee)

void main() {
  vec3 color = texture(srcTexture, texCoord).rgb;
  color = min(vec3(params.y), color);
  if (softThreshold == 1) {
    float brightness = max(color.r, max(color.g, color.b));
    float softness = clamp(brightness - params.z + params.w, 0.0, 2.0 * params.w);
    softness = (softness * softness) / (4.0 * params.w + 1e-4);
    float multiplier = max(brightness - params.z, softness) / max(brightness, 1e-4);
    color *= multiplier;
  }
  level = color;
}
