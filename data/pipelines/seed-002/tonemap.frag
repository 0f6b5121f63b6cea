#version 330 core
// bloomref's own shader with the interface of seed 002's final pass (FragShader_ToneMap): the
// scene tone-mapped with exposure 0.5, then the 3x3 tent of bloomMip0 (2 / size apart, size the
// scene's) times 0.02 added, then gamma 2.2.
out vec4 FragColor;
in vec2 texCoord;
uniform sampler2D finalHdrTex;
uniform sampler2D bloomMip0;
uniform vec2 size;

void main() {
  vec2 unit = 2.0 / size;
  vec3 bloom = vec3(0.0);
  for (int j = -1; j <= 1; ++j)
    for (int i = -1; i <= 1; ++i)
      bloom += texture(bloomMip0, texCoord + vec2(i, j) * unit).rgb *
               (float((2 - abs(i)) * (2 - abs(j))) / 16.0);
  vec3 mapped = vec3(1.0) - exp(-texture(finalHdrTex, texCoord).rgb * 0.5);
  mapped += bloom * 0.02;
  FragColor = vec4(pow(mapped, vec3(1.0 / 2.2)), 1.0);
}
