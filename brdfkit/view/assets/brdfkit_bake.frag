// Bake: one layer (theta_h index u_layer) of a decoded table, one channel a pass (the
// other channels masked): fragment (x, y) is the cell (phi_d x, theta_d y). The target is
// the 3D texture brdfkit_eval reads (RGBA float32, brdfkit_scale 1).
#pragma brdfkit require(brdfkit_decode.glsl)
uniform int u_layer;
out vec4 frag;

void main() {
  frag = vec4(brdfkit_cell(ivec3(int(gl_FragCoord.x), int(gl_FragCoord.y), u_layer)));
}
