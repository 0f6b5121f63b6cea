#version 330 core
// bloomref's own shader with the interface of seed 002's mip-chain filter (one program for both
// directions, ../shared/seeds/002_721f55a62a22b6ef.txt, FragShader_BloomFilter): prevTex is the
// level read, curTex the level an upsample adds to, size the target's size. Downsample: 13
// lookups 0.5 / size apart (one texel of a source twice the target's size), thresholded at
// luminance 1 on the first level, weighted 1/8 (centre, inner four), 1/32 (corners) and 1/16
// (edges). Upsample: curTex plus the 3x3 tent of prevTex, 2 / size apart.
// The pipeline description data/pipelines/seed-002.json runs it (docs/check.md).
out vec4 FragColor;
in vec2 texCoord;
uniform sampler2D prevTex;
uniform sampler2D curTex;
uniform bool isDownSample;
uniform bool firstDownSample = false;
uniform vec2 size;

vec3 lookup(vec2 steps, vec2 unit) {
  vec3 c = texture(prevTex, texCoord + steps * unit).rgb;
  if (firstDownSample && dot(c, vec3(0.2126, 0.7152, 0.0722)) < 1.0) c = vec3(0.0);
  return c;
}

vec3 down() {
  vec2 unit = 0.5 / size;
  vec3 sum = lookup(vec2(0.0), unit) * 0.125;
  sum += (lookup(vec2(-1.0, -1.0), unit) + lookup(vec2(1.0, -1.0), unit) +
          lookup(vec2(1.0, 1.0), unit) + lookup(vec2(-1.0, 1.0), unit)) * 0.125;
  sum += (lookup(vec2(-2.0, -2.0), unit) + lookup(vec2(2.0, -2.0), unit) +
          lookup(vec2(2.0, 2.0), unit) + lookup(vec2(-2.0, 2.0), unit)) * 0.03125;
  sum += (lookup(vec2(0.0, -2.0), unit) + lookup(vec2(2.0, 0.0), unit) +
          lookup(vec2(0.0, 2.0), unit) + lookup(vec2(-2.0, 0.0), unit)) * 0.0625;
  return sum;
}

vec3 up() {
  vec2 unit = 2.0 / size;
  vec3 sum = texture(curTex, texCoord).rgb;
  for (int j = -1; j <= 1; ++j)
    for (int i = -1; i <= 1; ++i)
      sum += texture(prevTex, texCoord + vec2(i, j) * unit).rgb *
             (float((2 - abs(i)) * (2 - abs(j))) / 16.0);
  return sum;
}

void main() {
  FragColor = vec4(isDownSample ? down() : up(), 1.0);
}
