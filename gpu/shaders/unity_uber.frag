#version 330 core
// Where Unity URP's bloom meets the scene (UberPost.shader, BLOOM_LQ, no lens dirt): one
// bilinear lookup of the first level's upsample, times the intensity, times the tint (white),
// added to the scene. bloomref's own GLSL of it: `compare` runs it for preset unity-urp.
in vec2 texCoord;
layout(location = 0) out vec4 color;
uniform sampler2D srcTexture;   // the scene
uniform sampler2D bloomTexture;  // up.1 (down.1 when the chain has one level)
uniform float intensity;

void main() {
  vec3 scene = texelFetch(srcTexture, ivec2(gl_FragCoord.xy), 0).rgb;
  vec3 bloom = texture(bloomTexture, texCoord).rgb;
  bloom *= intensity;
  color = vec4(scene + bloom, 1.0);
}
