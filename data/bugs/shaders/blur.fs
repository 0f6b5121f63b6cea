#version 330 core
// One single-direction pass of the discrete 9-tap Gaussian (docs/design.md "Specification",
// stage 3): the centre tap and four pairs i texels away, weights 924, 792, 495, 220 and 66 over
// 4070. Written for bloomref's bug corpus with the tutorial's interface.
out vec4 FragColor;
in vec2 TexCoords;
uniform sampler2D image;
uniform bool horizontal;
uniform float weight[5] = float[](0.2270270270, 0.1945945946, 0.1216216216, 0.0540540541, 0.0162162162);
void main() {
  vec2 texel = 1.0 / vec2(textureSize(image, 0));
  vec2 step = horizontal ? vec2(texel.x, 0.0) : vec2(0.0, texel.y);
  vec3 sum = texture(image, TexCoords).rgb * weight[0];
  for (int i = 1; i < 5; ++i) {
    sum += texture(image, TexCoords + step * float(i)).rgb * weight[i];
    sum += texture(image, TexCoords - step * float(i)).rgb * weight[i];
  }
  FragColor = vec4(sum, 1.0);
}
