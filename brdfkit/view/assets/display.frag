// A tile as the screen shows it (brdfkit.render.display: radiance times the exposure,
// clipped to [0, 1], sRGB OETF), or its CIEDE2000 difference from the reference tile
// (brdfkit.evaluation.metrics.delta_e_2000_map: display-linear sRGB -> XYZ -> L*a*b*, D65)
// in the inferno colours of `brdfkit compare`, 0 to u_de_max. The exposure's base, the
// matrix, the white and the colour map are brdfkit's (brdfkit.view.page writes them).
uniform highp sampler2D u_image;
uniform highp sampler2D u_reference;
uniform highp sampler2D u_inferno;  // matplotlib's inferno: 256 x 1, 8-bit
uniform int u_view;            // 0: the image, 1: Delta E 2000 against the reference
uniform float u_exposure;
uniform float u_de_max;
uniform vec2 u_origin;
uniform mat3 u_rgb_to_xyz;     // linear sRGB -> CIE XYZ (colour-science's sRGB)
uniform vec3 u_white;          // CIE XYZ of D65
out vec4 frag;

vec3 display_linear(vec3 x) { return clamp(x * u_exposure, 0.0, 1.0); }

vec3 srgb_oetf(vec3 x) {
  vec3 hi = 1.055 * pow(max(x, vec3(0.0031308)), vec3(1.0 / 2.4)) - 0.055;
  return mix(hi, 12.92 * x, vec3(lessThanEqual(x, vec3(0.0031308))));
}

float lab_f(float t) {
  const float d = 6.0 / 29.0;
  return t > d * d * d ? pow(t, 1.0 / 3.0) : t / (3.0 * d * d) + 4.0 / 29.0;
}

vec3 lab(vec3 rgb) {
  vec3 xyz = u_rgb_to_xyz * rgb / u_white;
  vec3 f = vec3(lab_f(xyz.x), lab_f(xyz.y), lab_f(xyz.z));
  return vec3(116.0 * f.y - 16.0, 500.0 * (f.x - f.y), 200.0 * (f.y - f.z));
}

float hue_deg(float b, float a) {
  if (a == 0.0 && b == 0.0) return 0.0;
  float h = degrees(atan(b, a));
  return h < 0.0 ? h + 360.0 : h;
}

// CIEDE2000 (Sharma, Wu and Dalal 2005), kL = kC = kH = 1.
float delta_e_2000(vec3 l1, vec3 l2) {
  float c1 = length(l1.yz), c2 = length(l2.yz);
  float cm = 0.5 * (c1 + c2);
  float cm7 = pow(cm, 7.0);
  float g = 0.5 * (1.0 - sqrt(cm7 / (cm7 + 6103515625.0)));
  float a1 = (1.0 + g) * l1.y, a2 = (1.0 + g) * l2.y;
  float cp1 = length(vec2(a1, l1.z)), cp2 = length(vec2(a2, l2.z));
  float h1 = hue_deg(l1.z, a1), h2 = hue_deg(l2.z, a2);
  float dl = l2.x - l1.x, dc = cp2 - cp1;
  float dh = 0.0;
  if (cp1 * cp2 != 0.0) {
    dh = h2 - h1;
    if (dh > 180.0) dh -= 360.0; else if (dh < -180.0) dh += 360.0;
  }
  float dhh = 2.0 * sqrt(cp1 * cp2) * sin(radians(0.5 * dh));
  float lm = 0.5 * (l1.x + l2.x), cpm = 0.5 * (cp1 + cp2);
  float hm = h1 + h2;
  if (cp1 * cp2 != 0.0) {
    if (abs(h1 - h2) <= 180.0) hm *= 0.5;
    else hm = h1 + h2 < 360.0 ? 0.5 * (hm + 360.0) : 0.5 * (hm - 360.0);
  }
  float t = 1.0 - 0.17 * cos(radians(hm - 30.0)) + 0.24 * cos(radians(2.0 * hm))
          + 0.32 * cos(radians(3.0 * hm + 6.0)) - 0.20 * cos(radians(4.0 * hm - 63.0));
  float dtheta = 30.0 * exp(-pow((hm - 275.0) / 25.0, 2.0));
  float cpm7 = pow(cpm, 7.0);
  float rc = 2.0 * sqrt(cpm7 / (cpm7 + 6103515625.0));
  float l50 = (lm - 50.0) * (lm - 50.0);
  float sl = 1.0 + 0.015 * l50 / sqrt(20.0 + l50);
  float sc = 1.0 + 0.045 * cpm, sh = 1.0 + 0.015 * cpm * t;
  float rt = -sin(radians(2.0 * dtheta)) * rc;
  float x = dl / sl, y = dc / sc, z = dhh / sh;
  return sqrt(max(x * x + y * y + z * z + rt * y * z, 0.0));
}

// The colour of t in [0, 1] as matplotlib's Colormap picks it: entry floor(256 t), the
// last for t = 1.
vec3 inferno(float t) {
  int i = min(int(floor(clamp(t, 0.0, 1.0) * 256.0)), 255);
  return texelFetch(u_inferno, ivec2(i, 0), 0).rgb;
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy - u_origin);
  vec4 img = texelFetch(u_image, p, 0);
  if (u_view == 0) {
    frag = vec4(srgb_oetf(display_linear(img.rgb)), 1.0);
    return;
  }
  vec4 ref = texelFetch(u_reference, p, 0);
  float de = delta_e_2000(lab(display_linear(ref.rgb)), lab(display_linear(img.rgb)));
  frag = vec4(inferno(de / u_de_max), 1.0);
}
