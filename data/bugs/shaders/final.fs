#version 330 core
// Composite, tone map and gamma in one pass (docs/design.md "Specification", stages 4-6):
// scene + bloom, 1 - exp(-hdr * exposure), pow(max(x, 0), 1 / 2.2). Written for bloomref's bug
// corpus with the tutorial's interface.
out vec4 FragColor;
in vec2 TexCoords;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform bool bloom;
uniform float exposure;
void main() {
  vec3 hdr = texture(scene, TexCoords).rgb;
  vec3 glow = texture(bloomBlur, TexCoords).rgb;
  if (bloom)
    hdr += glow;
  vec3 mapped = vec3(1.0) - exp(-hdr * exposure);
  FragColor = vec4(pow(max(mapped, 0.0), vec3(1.0 / 2.2)), 1.0);
}
