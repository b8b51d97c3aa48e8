// brdfkit_cell(cell): one colour channel of a basis or residual embedding, decoded at a
// cell of the MERL grid, exactly as brdfkit decodes it (brdfkit.residual.model.BasisResidual
// and brdfkit.basis.model.PcaBasis.decode_mapped):
//
//   x'  = mean + sum_k c_k U_k + gain f(HD(cell); W(c / sigma))     (the mapped value)
//   rho = max((exp(x') - 1)(x_ref + eps) + x_ref, bound) / w          (brdfkit.basis.mapping)
//
// with w = max(cos_i cos_o, w_floor) the cell's cosine weight, bound =
// min(floor x_ref, cap) + tiny min(w / w_tiny, 1), and f the residual's hyponet
// 6 -> W -> W -> 1 (ReLU) at the cell's HD vector (brdfkit.residual.network.evaluate), its
// weights made by the residual's hypernetwork from the channel's coefficients (the page
// does that in JavaScript, live.js; an engine takes them from material.json).
// Returns -1 where the basis has no cell (unmeasured: brdfkit_eval leaves it out).
//
// Textures: brdfkit_basis0 .. brdfkit_basis<T-1>, 3D, 180 x 90 x 90 (phi_d, theta_d,
// theta_h), RGBA float32: (x_ref, mean, U_0, U_1), (U_2 .. U_5), ...; x_ref -1 off the
// basis. BRDFKIT_TEXTURES = T, BRDFKIT_WIDTH = W (a multiple of 4; 0: no correction).
uniform highp sampler3D brdfkit_basis0;
#if BRDFKIT_TEXTURES > 1
uniform highp sampler3D brdfkit_basis1;
#endif
#if BRDFKIT_TEXTURES > 2
uniform highp sampler3D brdfkit_basis2;
#endif
#if BRDFKIT_TEXTURES > 3
uniform highp sampler3D brdfkit_basis3;
#endif
#if BRDFKIT_TEXTURES > 4
uniform highp sampler3D brdfkit_basis4;
#endif
#if BRDFKIT_TEXTURES > 5
uniform highp sampler3D brdfkit_basis5;
#endif
#if BRDFKIT_TEXTURES > 6
uniform highp sampler3D brdfkit_basis6;
#endif
#if BRDFKIT_TEXTURES > 7
uniform highp sampler3D brdfkit_basis7;
#endif
uniform vec4 brdfkit_coefficients[BRDFKIT_TEXTURES];  // the channel's: (0, 1, c_0, c_1), (c_2 .. c_5), ...
uniform vec4 brdfkit_mapping;                          // eps, floor, cap, w_floor
uniform vec2 brdfkit_tiny;                             // tiny, w_tiny
uniform float brdfkit_gain;                            // the correction's weight (0: the basis alone)
#if BRDFKIT_WIDTH > 0
#define BRDFKIT_W4 (BRDFKIT_WIDTH / 4)
// The channel's hyponet: w1 (6 rows of W), b1, w2 (W rows of W), b2, w3, b3, 4 a vector.
uniform vec4 brdfkit_net[9 * BRDFKIT_W4 + BRDFKIT_WIDTH * BRDFKIT_W4 + 1];

float brdfkit_hyponet(float hd[6]) {
  vec4 h1[BRDFKIT_W4], h2[BRDFKIT_W4];
  for (int j = 0; j < BRDFKIT_W4; j++) {
    vec4 a = brdfkit_net[6 * BRDFKIT_W4 + j];
    for (int i = 0; i < 6; i++) a += hd[i] * brdfkit_net[i * BRDFKIT_W4 + j];
    h1[j] = max(a, 0.0);
    h2[j] = brdfkit_net[7 * BRDFKIT_W4 + BRDFKIT_WIDTH * BRDFKIT_W4 + j];
  }
  for (int i = 0; i < BRDFKIT_W4; i++) {
    vec4 a = h1[i];
    int row = 7 * BRDFKIT_W4 + 4 * i * BRDFKIT_W4;
    for (int j = 0; j < BRDFKIT_W4; j++) {
      h2[j] += a.x * brdfkit_net[row + j] + a.y * brdfkit_net[row + BRDFKIT_W4 + j]
             + a.z * brdfkit_net[row + 2 * BRDFKIT_W4 + j] + a.w * brdfkit_net[row + 3 * BRDFKIT_W4 + j];
    }
  }
  float out_ = brdfkit_net[9 * BRDFKIT_W4 + BRDFKIT_WIDTH * BRDFKIT_W4].x;
  for (int j = 0; j < BRDFKIT_W4; j++) out_ += dot(max(h2[j], 0.0), brdfkit_net[8 * BRDFKIT_W4 + BRDFKIT_WIDTH * BRDFKIT_W4 + j]);
  return out_;
}
#endif

float brdfkit_cell(ivec3 cell) {
  vec4 t0 = texelFetch(brdfkit_basis0, cell, 0);
  float ref = t0.x;
  if (ref < 0.0) return -1.0;
  float mapped = dot(t0, brdfkit_coefficients[0]);
#if BRDFKIT_TEXTURES > 1
  mapped += dot(texelFetch(brdfkit_basis1, cell, 0), brdfkit_coefficients[1]);
#endif
#if BRDFKIT_TEXTURES > 2
  mapped += dot(texelFetch(brdfkit_basis2, cell, 0), brdfkit_coefficients[2]);
#endif
#if BRDFKIT_TEXTURES > 3
  mapped += dot(texelFetch(brdfkit_basis3, cell, 0), brdfkit_coefficients[3]);
#endif
#if BRDFKIT_TEXTURES > 4
  mapped += dot(texelFetch(brdfkit_basis4, cell, 0), brdfkit_coefficients[4]);
#endif
#if BRDFKIT_TEXTURES > 5
  mapped += dot(texelFetch(brdfkit_basis5, cell, 0), brdfkit_coefficients[5]);
#endif
#if BRDFKIT_TEXTURES > 6
  mapped += dot(texelFetch(brdfkit_basis6, cell, 0), brdfkit_coefficients[6]);
#endif
#if BRDFKIT_TEXTURES > 7
  mapped += dot(texelFetch(brdfkit_basis7, cell, 0), brdfkit_coefficients[7]);
#endif
  const float HALF_PI = 1.57079632679490;
  float i = float(cell.z);
  float th = i * i / 8100.0 * HALF_PI, td = float(cell.y) / 90.0 * HALF_PI;
  float pd = float(cell.x) / 180.0 * 3.14159265358979;
  float st = sin(th), ct = cos(th), sd = sin(td), cd = cos(td);
#if BRDFKIT_WIDTH > 0
  if (brdfkit_gain != 0.0) {
    float hd[6] = float[6](st, 0.0, ct, sd * cos(pd), sd * sin(pd), cd);
    mapped += brdfkit_gain * brdfkit_hyponet(hd);
  }
#endif
  float a = ct * cd, b = st * sd * cos(pd);
  float w = max(a - b, 0.0) * max(a + b, 0.0);
  // Every cell of a basis has w > 0 (in float64): where float32 rounds it to 0, the floor.
  w = max(max(w, brdfkit_mapping.w), 1e-30);
  float x = (exp(mapped) - 1.0) * (ref + brdfkit_mapping.x) + ref;
  float bound = min(brdfkit_mapping.y * ref, brdfkit_mapping.z) + brdfkit_tiny.x * min(w / brdfkit_tiny.y, 1.0);
  return max(x, bound) / w;
}
