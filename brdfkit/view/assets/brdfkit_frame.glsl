// The local frame of a world normal n: tangent, bitangent, n as the columns of a matrix
// (local -> world), continuous for n.z > -1 (Duff et al. 2017), as brdfkit render's
// brdfkit.render.nodes.frames.
mat3 brdfkit_frame(vec3 n) {
  float s = n.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (s + n.z);
  float b = n.x * n.y * a;
  return mat3(vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3(b, s + n.y * n.y * a, -n.y), n);
}
