// Stage `blur.k`: one single-direction pass (seed 000's blur shader), GL_LINEAR and
// GL_CLAMP_TO_EDGE set on `image`. Kernels as in reference/src/kernel.cpp:
//  discrete9: seed 004's 10-digit constants (924, 792, 495, 220, 66 over 4070);
//  linear5: rastergrid's linear sampling (seed 002).
uniform sampler2D image;
uniform bool horizontal;

#ifdef KERNEL_LINEAR5
const int N = 3;
const float offset[3] = float[](0.0, 1.3846153846, 3.2307692308);
const float weight[3] = float[](0.2270270270, 0.3162162162, 0.0702702703);
#else
const int N = 5;
const float offset[5] = float[](0.0, 1.0, 2.0, 3.0, 4.0);
const float weight[5] = float[](0.2270270270, 0.1945945946, 0.1216216216, 0.0540540541, 0.0162162162);
#endif

void run_stage(vec2 frag_coord) {
  vec2 size = vec2(textureSize(image, 0));
  vec2 uv = frag_coord / size;
  vec2 tex_offset = 1.0 / size;  // the size of one texel
  vec3 result = texture(image, uv).rgb * weight[0];
  for (int i = 1; i < N; ++i) {
    vec2 d = horizontal ? vec2(tex_offset.x * offset[i], 0.0) : vec2(0.0, tex_offset.y * offset[i]);
    result += texture(image, uv + d).rgb * weight[i];
    result += texture(image, uv - d).rgb * weight[i];
  }
  emit0(vec4(result, 1.0));
}
