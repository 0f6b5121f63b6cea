#version 330 core
// The final pass with the interface of LearnOpenGL's "Physically Based Bloom" host code:
// mix(scene, bloom, bloomStrength) for programChoice 3 (the scene alone otherwise), the
// exponential tone map and gamma 2.2. bloomref's own: `compare` runs it for preset
// learnopengl-pbb, and the bug corpus (data/bugs/) changes it.
in vec2 TexCoords;
out vec4 FragColor;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform float exposure;
uniform float bloomStrength = 0.04;
uniform int programChoice;

void main() {
  vec3 hdr = texture(scene, TexCoords).rgb;
  if (programChoice == 3)
    hdr = mix(hdr, texture(bloomBlur, TexCoords).rgb, bloomStrength);
  vec3 mapped = vec3(1.0) - exp(-hdr * exposure);
  FragColor = vec4(pow(max(mapped, 0.0), vec3(1.0 / 2.2)), 1.0);
}
