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
// weights made by the residual's hypernetwork from the channel's coefficients.
// Returns -1 where the basis has no cell (unmeasured: brdfkit_eval leaves it out).
//
// Every layout here is brdfkit.view.live's, given as defines and uniforms (material.json;
// the page sets the same): the basis's slots (x_ref, mean, U_0, ...) four a texture in
// brdfkit_basis[0 .. BRDFKIT_TEXTURES - 1] (3D, 180 x 90 x 90, RGBA float32; x_ref, slot 0,
// is -1 off the basis), BRDFKIT_TAPS the sum of the BRDFKIT_TAP(t), the mapping's
// constants in brdfkit_mapping at the indices BRDFKIT_MAPPING_<NAME>, and the hyponet's
// weights in brdfkit_net at the offsets BRDFKIT_NET_<TENSOR> (BRDFKIT_WIDTH 0: no
// correction).
#pragma brdfkit require(brdfkit_grid.glsl)
uniform highp sampler3D brdfkit_basis[BRDFKIT_TEXTURES];
uniform vec4 brdfkit_coefficients[BRDFKIT_TEXTURES];  // the channel's coefficient of each slot
uniform float brdfkit_mapping[BRDFKIT_MAPPING_SIZE];
uniform float brdfkit_gain;                           // the correction's weight (0: the basis alone)
#define BRDFKIT_TAP(t) dot(texelFetch(brdfkit_basis[t], cell, 0), brdfkit_coefficients[t])
#if BRDFKIT_WIDTH > 0
#define BRDFKIT_R BRDFKIT_NET_ROW
// The channel's hyponet: w1 (6 rows), b1, w2 (W rows), b2, w3, b3; a row is BRDFKIT_R vec4.
uniform vec4 brdfkit_net[BRDFKIT_NET_SIZE];

float brdfkit_hyponet(float hd[6]) {
  vec4 h1[BRDFKIT_R], h2[BRDFKIT_R];
  for (int j = 0; j < BRDFKIT_R; j++) {
    vec4 a = brdfkit_net[BRDFKIT_NET_B1 + j];
    for (int i = 0; i < 6; i++) a += hd[i] * brdfkit_net[BRDFKIT_NET_W1 + i * BRDFKIT_R + j];
    h1[j] = max(a, 0.0);
    h2[j] = brdfkit_net[BRDFKIT_NET_B2 + j];
  }
  for (int i = 0; i < BRDFKIT_R; i++) {
    vec4 a = h1[i];
    int row = BRDFKIT_NET_W2 + 4 * i * BRDFKIT_R;
    for (int j = 0; j < BRDFKIT_R; j++) {
      h2[j] += a.x * brdfkit_net[row + j] + a.y * brdfkit_net[row + BRDFKIT_R + j]
             + a.z * brdfkit_net[row + 2 * BRDFKIT_R + j] + a.w * brdfkit_net[row + 3 * BRDFKIT_R + j];
    }
  }
  float out_ = brdfkit_net[BRDFKIT_NET_B3].x;
  for (int j = 0; j < BRDFKIT_R; j++) out_ += dot(max(h2[j], 0.0), brdfkit_net[BRDFKIT_NET_W3 + j]);
  return out_;
}
#endif

float brdfkit_cell(ivec3 cell) {
  float ref = texelFetch(brdfkit_basis[0], cell, 0).x;
  if (ref < 0.0) return -1.0;
  float mapped = BRDFKIT_TAPS;
  vec3 a = brdfkit_cell_angles(cell);
  float st = sin(a.x), ct = cos(a.x), sd = sin(a.y), cd = cos(a.y);
#if BRDFKIT_WIDTH > 0
  if (brdfkit_gain != 0.0) {
    float hd[6] = float[6](st, 0.0, ct, sd * cos(a.z), sd * sin(a.z), cd);
    mapped += brdfkit_gain * brdfkit_hyponet(hd);
  }
#endif
  float eps = brdfkit_mapping[BRDFKIT_MAPPING_EPS];
  float u = ct * cd, v = st * sd * cos(a.z);
  float w = max(u - v, 0.0) * max(u + v, 0.0);
  // Every cell of a basis has w > 0 (in float64): where float32 rounds it to 0, the floor.
  w = max(max(w, brdfkit_mapping[BRDFKIT_MAPPING_W_FLOOR]), 1e-30);
  float share = brdfkit_mapping[BRDFKIT_MAPPING_SHARE];
  float near = min(w / brdfkit_mapping[BRDFKIT_MAPPING_W_TINY], 1.0);
  if (share == 0.0) {  // Nielsen's mapping
    float x = (exp(mapped) - 1.0) * (ref + eps) + ref;
    float bound = min(brdfkit_mapping[BRDFKIT_MAPPING_FLOOR] * ref, brdfkit_mapping[BRDFKIT_MAPPING_CAP])
                + brdfkit_mapping[BRDFKIT_MAPPING_TINY] * near;
    return max(x, bound) / w;
  }
  // A mapping that resolves grazing cells (brdfkit.basis.mapping.LogMapping).
  float e = clamp(ref * max(ref / eps, share), brdfkit_mapping[BRDFKIT_MAPPING_E_MIN], eps);
  float s = (ref + e) / (ref + eps);
  float x = (exp(min(mapped / s, brdfkit_mapping[BRDFKIT_MAPPING_Z_MAX])) - 1.0) * (ref + e) + ref;
  float bound = min(brdfkit_mapping[BRDFKIT_MAPPING_SHARE_FLOOR] * ref, brdfkit_mapping[BRDFKIT_MAPPING_CAP])
              + brdfkit_mapping[BRDFKIT_MAPPING_E_MIN] * near;
  return max(x, bound) / w;
}
