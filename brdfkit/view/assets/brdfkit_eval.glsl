// brdfkit_eval(wi, wo): a BRDF table on the MERL grid, looked up as `brdfkit render` looks
// tables up (brdfkit.geometry.trilinear.lookup_trilinear): trilinear in the grid's own
// coordinates (brdfkit_grid.glsl), phi_d wrapped, unmeasured corners left out and the
// weights renormalised over the rest; 0 where no corner is measured and where wi or wo is
// below the horizon.
//
// brdfkit_table: a 3D texture of width 180 (phi_d), height 90 (theta_d) and depth 90
// (theta_h), the MERL file's flat order; red, green, blue times brdfkit_scale = BRDF in
// 1/sr; red -1: not measured. Directions are unit vectors in the local frame, z the normal.
#pragma brdfkit require(brdfkit_grid.glsl)
uniform highp sampler3D brdfkit_table;
uniform float brdfkit_scale;

// (theta_h, theta_d, phi_d) of a direction pair (brdfkit.geometry.half_diff_from_io).
vec3 brdfkit_half_diff(vec3 wi, vec3 wo) {
  vec3 s = wi + wo;
  vec3 h = s / max(length(s), 1e-30);
  float th = brdfkit_atan2(length(h.xy), h.z);
  float ph = brdfkit_atan2(h.y, h.x);
  float cp = cos(ph), sp = sin(ph), ct = cos(th), st = sin(th);
  float x1 = cp * wi.x + sp * wi.y;
  float y1 = -sp * wi.x + cp * wi.y;
  float dx = ct * x1 - st * wi.z;
  float dz = st * x1 + ct * wi.z;
  return vec3(th, brdfkit_atan2(length(vec2(dx, y1)), dz), brdfkit_atan2(y1, dx));
}

vec3 brdfkit_eval(vec3 wi, vec3 wo) {
  if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
  vec3 f = brdfkit_grid_coords(brdfkit_half_diff(wi, wo));
  vec3 c0 = floor(f);
  vec3 fr = f - c0;
  ivec3 lo = ivec3(int(c0.z) % 180, clamp(int(c0.y), 0, 89), clamp(int(c0.x), 0, 89));
  ivec3 hi = ivec3((int(c0.z) + 1) % 180, clamp(int(c0.y) + 1, 0, 89), clamp(int(c0.x) + 1, 0, 89));
  vec3 acc = vec3(0.0);
  float wsum = 0.0;
  for (int i = 0; i < 8; i++) {
    bvec3 up = bvec3((i & 1) != 0, (i & 2) != 0, (i & 4) != 0);  // (phi_d, theta_d, theta_h)
    vec3 t = mix(vec3(1.0) - fr.zyx, fr.zyx, up);
    vec3 v = texelFetch(brdfkit_table, ivec3(up.x ? hi.x : lo.x, up.y ? hi.y : lo.y, up.z ? hi.z : lo.z), 0).rgb;
    if (v.r >= 0.0) {
      float w = t.z * t.y * t.x;
      acc += w * v;
      wsum += w;
    }
  }
  return wsum > 0.0 ? acc / wsum * brdfkit_scale : vec3(0.0);
}
