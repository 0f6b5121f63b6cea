#version 330 core
// After Bevy's bloom: bloomref's tone map and gamma on the composite, each texel read with
// texelFetch at its own position (Bevy's own tone mappers are not modelled; docs/presets.md).
// bloomref's own: `compare` runs it for preset bevy.
in vec2 texCoord;
out vec4 color;
uniform sampler2D srcTexture;
uniform float exposure;
uniform float gamma;

void main() {
  vec3 hdr = texelFetch(srcTexture, ivec2(gl_FragCoord.xy), 0).rgb;
  vec3 mapped = vec3(1.0) - exp(-hdr * exposure);
  color = vec4(pow(max(mapped, 0.0), vec3(1.0 / gamma)), 1.0);
}
