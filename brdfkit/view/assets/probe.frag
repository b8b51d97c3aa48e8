// The in-plane lobe of `brdfkit plot` (brdfkit.figures.brdf_plot.inplane_lobe): fragment x
// is its theta_o sample x (brdfkit.figures.brdf_plot.THETA_O_DEG: evenly spaced from
// u_theta_o.x by u_theta_o.y degrees), wi = (-sin theta_i, 0, cos theta_i).
#pragma brdfkit require(brdfkit_eval.glsl)
uniform float u_theta_i;       // radians
uniform vec2 u_theta_o;        // the first theta_o and the step, degrees
out vec4 frag;

void main() {
  float to = radians(u_theta_o.x + u_theta_o.y * floor(gl_FragCoord.x));
  vec3 wi = vec3(-sin(u_theta_i), 0.0, cos(u_theta_i));
  vec3 wo = vec3(sin(to), 0.0, cos(to));
  frag = vec4(brdfkit_eval(wi, wo), 1.0);
}
