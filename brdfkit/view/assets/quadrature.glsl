// The reference scene's environment light at one pixel, as `brdfkit render` integrates it
// (brdfkit.render.quadrature and brdfkit.render.pairs): the same cosine (C), half-vector (B)
// and light (A) nodes, the same shares between them (brdfkit.render.shares) and the same
// per-pixel normalisation, in float32. The node constants (u_nodes rows 0-5) and every
// uniform here are the renderer's, written by brdfkit.view.quadrature_data; Q_MAX_RECTS
// (a define) is its MAX_RECTS.
#pragma brdfkit require(brdfkit_eval.glsl)
#pragma brdfkit require(brdfkit_frame.glsl)
uniform highp sampler2D u_nodes;
uniform highp sampler2D u_env;
uniform ivec3 u_counts;        // N_C, N_B, N_A
uniform vec4 u_ring;           // e, c, half_phi, half_phi_min
uniform vec4 u_share;          // 1 / half_extent, log(handover lo), 1 / (log hi - log lo), d_C
uniform float u_share_power;
uniform int u_ib_count;
uniform int u_rect_count;
uniform vec4 u_rect[Q_MAX_RECTS];  // u0, u1, v0, v1
uniform vec2 u_ramp[Q_MAX_RECTS];  // ramp_u, ramp_v

float q_smooth(float x) {
  x = clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// (g, s_x, s_y) of theta_h: brdfkit.render.shares.theta_terms.
vec3 q_theta_terms(float th) {
  th = max(th, 1e-12);
  float lt = log(th);
  float s = sin(th);
  float m = max(sqrt(s) * u_ring.z, u_ring.w);
  float g = exp(u_ring.x * lt) * s * u_ring.y / m;
  return vec3(g, q_smooth(th * u_share.x), q_smooth((lt - u_share.y) * u_share.z));
}

float q_theta_h(vec3 wi, vec3 wo) {
  vec2 h = wi.xy + wo.xy;
  return brdfkit_atan2(length(h), wi.z + wo.z);
}

float q_ratio(float dc, float woh, float g) {
  float r = dc * max(woh, 1e-12) * g;
  return u_share_power == 1.0 ? r : pow(r, u_share_power);
}

// Texture coordinates of a world direction (brdfkit.render.shares.uv).
vec2 q_uv(vec3 d) {
  float u = brdfkit_atan2(d.x, -d.z) / (2.0 * BRDFKIT_PI);
  return vec2(u - floor(u), acos(clamp(d.y, -1.0, 1.0)) / BRDFKIT_PI);
}

// 1 - rho: 0 inside a light rectangle, 1 away from them (brdfkit.render.shares.outside).
float q_outside(vec2 uv) {
  float out_ = 1.0;
  for (int i = 0; i < Q_MAX_RECTS; i++) {
    if (i >= u_rect_count) break;
    vec4 r = u_rect[i];
    vec2 ramp = u_ramp[i];
    float o;
    if (r.y - r.x < 2.0 * ramp.x || r.w - r.z < 2.0 * ramp.y) {
      float uu = (r.x < 0.0 && uv.x < r.x) ? uv.x + 1.0 : uv.x;
      o = 1.0 - q_smooth((uu - r.x) / ramp.x) * q_smooth((r.y - uu) / ramp.x)
              * q_smooth((uv.y - r.z) / ramp.y) * q_smooth((r.w - uv.y) / ramp.y);
    } else {
      float du = uv.x - 0.5 * (r.x + r.y);
      if (r.x < 0.0 || r.y > 1.0) du -= floor(du + 0.5);
      float ou = q_smooth(abs(du) / ramp.x + 1.0 - (r.y - r.x) / (2.0 * ramp.x));
      float ov = q_smooth(abs(uv.y - 0.5 * (r.z + r.w)) / ramp.y + 1.0 - (r.w - r.z) / (2.0 * ramp.y));
      o = ou + ov - ou * ov;
    }
    out_ = min(out_, o);
  }
  return out_;
}

// Radiance of the environment at texture coordinates, bilinear as Mitsuba's envmap
// (brdfkit.render.shares.EnvLookup).
vec3 q_env(vec2 uv) {
  ivec2 size = textureSize(u_env, 0);
  float w = float(size.x);
  float x = (uv.x - 0.5 / w) * w;
  x -= floor(x / w) * w;
  float y = uv.y * float(size.y - 1);
  float x0 = clamp(floor(x), 0.0, w - 1.0);
  float y0 = clamp(floor(y), 0.0, float(size.y - 2));
  float fx = x - x0, fy = y - y0;
  int ix0 = int(x0), iy0 = int(y0);
  int ix1 = (ix0 + 1) % size.x;
  vec3 v00 = texelFetch(u_env, ivec2(ix0, iy0), 0).rgb, v01 = texelFetch(u_env, ivec2(ix1, iy0), 0).rgb;
  vec3 v10 = texelFetch(u_env, ivec2(ix0, iy0 + 1), 0).rgb, v11 = texelFetch(u_env, ivec2(ix1, iy0 + 1), 0).rgb;
  return (1.0 - fy) * ((1.0 - fx) * v00 + fx * v01) + fy * ((1.0 - fx) * v10 + fx * v11);
}

float q_ib(float cos_o) {
  float x = clamp(cos_o, 0.0, 1.0) * float(u_ib_count - 1);
  int i = min(int(floor(x)), u_ib_count - 2);
  float f = x - float(i);
  return (1.0 - f) * texelFetch(u_nodes, ivec2(i, 5), 0).x + f * texelFetch(u_nodes, ivec2(i + 1, 5), 0).x;
}

// Outgoing radiance towards the camera (world +z) at a point of world normal n.
vec3 quadrature_shade(vec3 n) {
  mat3 to_world = brdfkit_frame(n);
  vec3 t = to_world[0], bt = to_world[1];
  vec3 wo = vec3(t.z, bt.z, n.z);
  const vec3 wo_world = vec3(0.0, 0.0, 1.0);
  float dc = u_share.w;
  vec3 sum_a = vec3(0.0), sum_b = vec3(0.0), sum_c = vec3(0.0);
  float mass_a = 0.0, mass_3 = 0.0, mass_b = 0.0, mass_c = 0.0;
  for (int i = 0; i < u_counts.z; i++) {
    vec4 p = texelFetch(u_nodes, ivec2(i, 3), 0);
    vec4 q = texelFetch(u_nodes, ivec2(i, 4), 0);
    vec3 l = vec3(dot(t, p.xyz), dot(bt, p.xyz), dot(n, p.xyz));
    vec3 tt = q_theta_terms(q_theta_h(l, wo));
    float r = q_ratio(dc * max(l.z, 0.25), sqrt(0.5 * (1.0 + p.z)), tt.x);
    float geo = (l.z > 0.0 ? q.x * l.z : 0.0) * p.w / (1.0 + r);
    float cut = 1.0 - tt.y;
    float w = geo * (r + tt.y + cut * tt.z);
    mass_a += w;
    mass_3 += geo * cut * tt.z;
    if (w > 0.0) sum_a += q.yzw * w * brdfkit_eval(l, wo);
  }
  for (int i = 0; i < u_counts.y; i++) {
    vec4 p = texelFetch(u_nodes, ivec2(i, 1), 0);
    vec4 q = texelFetch(u_nodes, ivec2(i, 2), 0);
    float woh = dot(wo, p.xyz);
    float cos_b = 2.0 * woh * p.z - wo.z;
    if (woh <= 0.0 || cos_b <= 0.0) continue;
    float r = q_ratio(dc * max(cos_b, 0.25), woh, p.w);
    float w = q.w * woh * cos_b * q.x / (1.0 + r);
    vec2 uv = q_uv(2.0 * woh * (to_world * p.xyz) - wo_world);
    w *= q_outside(uv) * q.y + q.z;
    mass_b += w;
    if (w > 0.0) sum_b += q_env(uv) * w * brdfkit_eval(vec3(2.0 * woh * p.xy - wo.xy, cos_b), wo);
  }
  for (int i = 0; i < u_counts.x; i++) {
    vec4 p = texelFetch(u_nodes, ivec2(i, 0), 0);
    vec3 tt = q_theta_terms(q_theta_h(p.xyz, wo));
    float r = q_ratio(p.w, sqrt(0.5 * (dot(wo, p.xyz) + 1.0)), tt.x);
    vec2 uv = q_uv(to_world * p.xyz);
    float share = (r + tt.y) / (1.0 + r) * q_outside(uv);
    mass_c += share;
    if (share > 0.0) sum_c += q_env(uv) * share * brdfkit_eval(p.xyz, wo);
  }
  float nc = float(u_counts.x);
  mass_c /= nc;
  mass_b /= BRDFKIT_PI;
  mass_a /= BRDFKIT_PI;
  mass_3 /= BRDFKIT_PI;
  float target_b = q_ib(wo.z) - mass_3;
  float target_c = 1.0 - target_b - mass_a;
  float scale_c = mass_c > 1e-9 ? target_c / mass_c : 1.0;
  float scale_b = mass_b > 1e-9 ? target_b / mass_b : 1.0;
  return sum_c * (scale_c * BRDFKIT_PI / nc) + sum_b * scale_b + sum_a;
}
