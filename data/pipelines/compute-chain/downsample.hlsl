// downsample.comp in HLSL (glslang's HLSL front end): the same interface, with the texture and
// its sampler apart (binding 0 and 2, as HLSL declares them). The level it writes is declared
// rgba32f: glslang 12 (Debian 12) gives RWTexture2D<float4> that format and does not read
// [[vk::image_format]], so its targets are RGBA32F textures.
[[vk::binding(0)]] Texture2D<float4> uInputTexture;
[[vk::binding(2)]] SamplerState uSampler;
[[vk::binding(1)]] RWTexture2D<float4> uOutputTexture;

struct PushConstant {
  float width;
  float height;
};
[[vk::push_constant]] ConstantBuffer<PushConstant> pc;

float3 tap(float2 uv, float2 step, float x, float y) {
  return uInputTexture.SampleLevel(uSampler, uv + float2(x, y) * step, 0).rgb;
}

[numthreads(8, 8, 1)]
void main(uint3 id : SV_DispatchThreadID) {
  if (id.x >= uint(pc.width) || id.y >= uint(pc.height)) return;
  float2 uv = (float2(id.xy) + 0.5) / float2(pc.width, pc.height);
  uint w, h;
  uInputTexture.GetDimensions(w, h);
  float2 step = 1.0 / float2(w, h);
  float3 sum = tap(uv, step, 0.0, 0.0) * 0.125;
  sum += (tap(uv, step, -1.0, -1.0) + tap(uv, step, 1.0, -1.0) +
          tap(uv, step, -1.0, 1.0) + tap(uv, step, 1.0, 1.0)) * 0.125;
  sum += (tap(uv, step, 0.0, -2.0) + tap(uv, step, -2.0, 0.0) +
          tap(uv, step, 2.0, 0.0) + tap(uv, step, 0.0, 2.0)) * 0.0625;
  sum += (tap(uv, step, -2.0, -2.0) + tap(uv, step, 2.0, -2.0) +
          tap(uv, step, -2.0, 2.0) + tap(uv, step, 2.0, 2.0)) * 0.03125;
  uOutputTexture[id.xy] = float4(sum, 1.0);
}
