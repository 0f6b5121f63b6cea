// One triangle covering the viewport; fragment shaders address texels through gl_FragCoord,
// whose centres are exactly (x + 0.5, y + 0.5), so no interpolated coordinates are involved.
void main() {
  const vec2 corner[3] = vec2[](vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));
  gl_Position = vec4(corner[gl_VertexID], 0.0, 1.0);
}
