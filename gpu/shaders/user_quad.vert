#version 330 core
// bloomref's stand-in for a user's vertex shader (user_pipeline.h, preset learnopengl): hands
// the quad's corner through unchanged and interpolates its texture coordinate, under the name
// the tutorial's fragment shaders read (`in vec2 TexCoords`).
layout(location = 0) in vec3 aPos;
layout(location = 1) in vec2 aTexCoords;
out vec2 TexCoords;

void main() {
  gl_Position = vec4(aPos.xy, aPos.z, 1.0);
  TexCoords = aTexCoords;
}
