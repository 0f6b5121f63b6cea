// Entry point of a stage run as a fragment shader over a full-screen triangle (fullscreen.vert):
// one fragment per texel, frag_coord = gl_FragCoord.xy = (x + 0.5, y + 0.5).
layout(location = 0) out vec4 out0;
layout(location = 1) out vec4 out1;
uniform ivec2 u_target_size;  // the render target's size (set by the executor)
ivec2 target_size() { return u_target_size; }
void emit0(vec4 v) { out0 = v; }
void emit1(vec4 v) { out1 = v; }
void run_stage(vec2 frag_coord);
void main() { run_stage(gl_FragCoord.xy); }
