// The in-plane lobe of `brdfkit plot` (brdfkit.figures.brdf_plot.inplane_lobe): fragment x
// is theta_o = -89.5 + 0.5 x degrees, wi = (-sin theta_i, 0, cos theta_i).
uniform float u_theta_i;       // radians
out vec4 frag;

void main() {
  float to = radians(-89.5 + 0.5 * floor(gl_FragCoord.x));
  vec3 wi = vec3(-sin(u_theta_i), 0.0, cos(u_theta_i));
  vec3 wo = vec3(sin(to), 0.0, cos(to));
  frag = vec4(brdf(wi, wo), 1.0);
}
