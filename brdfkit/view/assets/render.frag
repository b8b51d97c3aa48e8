// One tile of the reference scene: the unit sphere under the orthographic camera on +z
// (brdfkit.render.scene), one sample at each pixel centre, linear radiance out (alpha 0:
// background). Lit by the scene's environment (quadrature.glsl) or by one directional light.
#pragma brdfkit require(quadrature.glsl)
uniform float u_size;          // pixels across the tile
uniform vec2 u_origin;         // the tile's lower left corner in the framebuffer
uniform float u_view_half_width;
uniform int u_light_mode;      // 0: environment, 1: directional
uniform vec3 u_light;          // world direction towards the directional light
uniform float u_irradiance;    // its irradiance at normal incidence
out vec4 frag;

void main() {
  vec2 p = gl_FragCoord.xy - u_origin;
  float x = (p.x / u_size * 2.0 - 1.0) * u_view_half_width;
  float y = (p.y / u_size * 2.0 - 1.0) * u_view_half_width;
  float r2 = x * x + y * y;
  if (r2 >= 1.0) {
    frag = vec4(0.0);
    return;
  }
  vec3 n = vec3(x, y, sqrt(max(1.0 - r2, 0.0)));
  vec3 radiance;
  if (u_light_mode == 0) {
    radiance = quadrature_shade(n);
  } else {
    mat3 to_local = transpose(brdfkit_frame(n));
    vec3 wi = to_local * u_light, wo = to_local * vec3(0.0, 0.0, 1.0);
    radiance = wi.z > 0.0 ? u_irradiance * wi.z * brdfkit_eval(wi, wo) : vec3(0.0);
  }
  frag = vec4(radiance, 1.0);
}
