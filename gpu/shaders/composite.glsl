// Stage `composite`: hdr = scene + strength * bloom (seed 000's additive blend); scene alpha.
uniform sampler2D scene;
uniform sampler2D bloom;
uniform float strength;

void run_stage(vec2 frag_coord) {
  ivec2 p = ivec2(frag_coord);
  vec4 s = texelFetch(scene, p, 0);
  vec3 b = texelFetch(bloom, p, 0).rgb;
  vec3 hdr = s.rgb + strength * b;
  emit0(vec4(hdr, s.a));
}
