// brdfkit_eval(wi, wo): a BRDF table on the MERL grid, looked up as `brdfkit render` looks
// tables up (brdfkit.geometry.trilinear.lookup_trilinear): trilinear in the grid's own
// coordinates (theta_h on its square-root spacing), theta clamped at pi/2, phi_d folded
// into [0, pi) and wrapped, unmeasured corners left out and the weights renormalised
// over the rest; 0 where no corner is measured and where wi or wo is below the horizon.
//
// brdfkit_table: a 3D texture of width 180 (phi_d), height 90 (theta_d) and depth 90
// (theta_h), the MERL file's flat order; red, green, blue times brdfkit_scale = BRDF in
// 1/sr; red -1: not measured. Directions are unit vectors in the local frame, z the normal.
uniform highp sampler3D brdfkit_table;
uniform float brdfkit_scale;

const float BRDFKIT_PI = 3.14159265358979;

float brdfkit_atan2(float y, float x) {
  return (x == 0.0 && y == 0.0) ? 0.0 : atan(y, x);
}

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

vec3 brdfkit_texel(int h, int d, int p) {
  return texelFetch(brdfkit_table, ivec3(p, d, h), 0).rgb;
}

vec3 brdfkit_eval(vec3 wi, vec3 wo) {
  if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
  vec3 a = brdfkit_half_diff(wi, wo);
  const float HALF_PI = 0.5 * BRDFKIT_PI;
  float uh = sqrt(clamp(a.x, 0.0, HALF_PI) / HALF_PI) * 90.0;
  float ud = clamp(a.y, 0.0, HALF_PI) / HALF_PI * 90.0;
  float up = (a.z - BRDFKIT_PI * floor(a.z / BRDFKIT_PI)) / BRDFKIT_PI * 180.0;
  if (up >= 180.0) up -= 180.0;
  up = max(up, 0.0);
  vec3 f = vec3(uh, ud, up);
  vec3 c0 = floor(f);
  vec3 fr = f - c0;
  int h0 = clamp(int(c0.x), 0, 89), h1 = clamp(int(c0.x) + 1, 0, 89);
  int d0 = clamp(int(c0.y), 0, 89), d1 = clamp(int(c0.y) + 1, 0, 89);
  int p0 = int(c0.z) % 180, p1 = (int(c0.z) + 1) % 180;
  vec3 acc = vec3(0.0);
  float wsum = 0.0;
  for (int i = 0; i < 8; i++) {
    bool bh = (i & 4) != 0, bd = (i & 2) != 0, bp = (i & 1) != 0;
    float w = (bh ? fr.x : 1.0 - fr.x) * (bd ? fr.y : 1.0 - fr.y) * (bp ? fr.z : 1.0 - fr.z);
    vec3 v = brdfkit_texel(bh ? h1 : h0, bd ? d1 : d0, bp ? p1 : p0);
    if (v.r >= 0.0) {
      acc += w * v;
      wsum += w;
    }
  }
  return wsum > 0.0 ? acc / wsum * brdfkit_scale : vec3(0.0);
}
