// The MERL grid (brdfkit.geometry.grid; Matusik et al. 2003): cell (phi_d p, theta_d d,
// theta_h h) of a 3D texture 180 x 90 x 90 sits at theta_h = (h / 90)^2 pi/2,
// theta_d = d / 90 pi/2, phi_d = p / 180 pi; brdfkit_grid_coords is the inverse, the
// fractional cell coordinates of a pair's angles (brdfkit.geometry.fractional_indices),
// theta clamped at pi/2 and phi_d folded into [0, pi) by reciprocity.
const float BRDFKIT_PI = 3.14159265358979;
const float BRDFKIT_HALF_PI = 1.57079632679490;

float brdfkit_atan2(float y, float x) {
  return (x == 0.0 && y == 0.0) ? 0.0 : atan(y, x);
}

// (theta_h, theta_d, phi_d) of a cell, radians.
vec3 brdfkit_cell_angles(ivec3 cell) {
  float h = float(cell.z);
  return vec3(h * h / 8100.0 * BRDFKIT_HALF_PI, float(cell.y) / 90.0 * BRDFKIT_HALF_PI,
              float(cell.x) / 180.0 * BRDFKIT_PI);
}

// (u_h, u_d, u_p): fractional cell coordinates of (theta_h, theta_d, phi_d).
vec3 brdfkit_grid_coords(vec3 a) {
  float uh = sqrt(clamp(a.x, 0.0, BRDFKIT_HALF_PI) / BRDFKIT_HALF_PI) * 90.0;
  float ud = clamp(a.y, 0.0, BRDFKIT_HALF_PI) / BRDFKIT_HALF_PI * 90.0;
  float up = (a.z - BRDFKIT_PI * floor(a.z / BRDFKIT_PI)) / BRDFKIT_PI * 180.0;
  if (up >= 180.0) up -= 180.0;
  return vec3(uh, ud, max(up, 0.0));
}
