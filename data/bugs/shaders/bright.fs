#version 330 core
// The scene pass's two outputs, as the tutorial's scene shader writes them: the scene at
// location 0, its bright part at location 1 (Rec. 709 luminance strictly above the threshold,
// docs/design.md "Specification", stage 2). Written for bloomref's bug corpus.
layout (location = 0) out vec4 FragColor;
layout (location = 1) out vec4 BrightColor;
in vec2 TexCoords;
uniform sampler2D scene;
uniform float threshold;
void main() {
  vec3 colour = texture(scene, TexCoords).rgb;
  FragColor = vec4(colour, 1.0);
  float luminance = dot(colour, vec3(0.2126, 0.7152, 0.0722));
  if (luminance > threshold)
    BrightColor = vec4(colour, 1.0);
  else
    BrightColor = vec4(0.0, 0.0, 0.0, 1.0);
}
