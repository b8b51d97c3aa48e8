// The page's 2D plots: the in-plane lobe of `brdfkit plot` (brdfkit.figures.brdf_plot),
// the Delta E colour scale, and the sample files' points; their colours are brdfkit's
// (the page's data.display: brdfkit plot's line colours, matplotlib's inferno).
'use strict';

// The inferno colour of t in [0, 1], picked as display.frag picks it.
function inferno(t, display) {
  const lut = display.inferno, n = lut.length / 4, i = Math.min(n - 1, Math.floor(Math.max(0, Math.min(1, t)) * n));
  return `rgb(${lut[4 * i]},${lut[4 * i + 1]},${lut[4 * i + 2]})`;
}

// Radius of a value on a log10 scale from lo to hi (decades), 0 below lo.
function logRadius(value, lo, hi) {
  return value > 0 ? Math.max(0, Math.min(1, (Math.log10(value) - lo) / (hi - lo))) : 0;
}

function drawLobe(canvas, lobes, thetaI, what, samples, settings, display) {
  const colours = display.lines;
  const ctx = canvas.getContext('2d'), w = canvas.width, h = canvas.height;
  const cx = w / 2, cy = h - 22, radius = Math.min(w / 2 - 12, h - 40);
  ctx.clearRect(0, 0, w, h);
  let peak = 0;
  for (const l of lobes) for (const v of l.values) if (v > peak && Number.isFinite(v)) peak = v;
  const decades = settings.decades;
  const hi = Math.ceil(Math.log10(peak > 0 ? peak : 1) - 1e-9), lo = hi - Math.ceil(decades);
  ctx.strokeStyle = '#ccc';
  ctx.fillStyle = '#666';
  ctx.font = '10px sans-serif';
  ctx.lineWidth = 1;
  for (let k = 0; k <= Math.ceil(decades); k += 2) {
    const r = radius * k / Math.ceil(decades);
    ctx.beginPath();
    ctx.arc(cx, cy, r, Math.PI, 2 * Math.PI);
    ctx.stroke();
    if (k > 0) {
      ctx.textAlign = 'center';
      ctx.fillText(`1e${lo + k}`, Math.min(cx + r, w - 14), cy + 12);
      ctx.textAlign = 'left';
    }
  }
  ctx.beginPath();
  ctx.moveTo(cx - radius, cy);
  ctx.lineTo(cx + radius, cy);
  ctx.moveTo(cx, cy);
  ctx.lineTo(cx, cy - radius);
  ctx.stroke();
  // The light comes in from the left at -theta_i.
  ctx.strokeStyle = '#e6a100';
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(cx - Math.sin(thetaI) * radius, cy - Math.cos(thetaI) * radius);
  ctx.lineTo(cx, cy);
  ctx.stroke();
  lobes.forEach((l, j) => {
    ctx.strokeStyle = colours[j % colours.length];
    ctx.lineWidth = 1.5;
    ctx.setLineDash(j < colours.length ? [] : [5, 3]);
    ctx.beginPath();
    let pen = false;
    l.values.forEach((v, i) => {
      const to = (settings.theta_o[i] * Math.PI) / 180, r = radius * logRadius(v, lo, hi);
      const x = cx + r * Math.sin(to), y = cy - r * Math.cos(to);
      if (v > 0 && pen) ctx.lineTo(x, y); else if (v > 0) ctx.moveTo(x, y);
      pen = v > 0;
    });
    ctx.stroke();
  });
  ctx.setLineDash([]);
  drawLobeSamples(ctx, samples, thetaI, cx, cy, radius, lo, hi, settings, colours);
  ctx.fillStyle = '#222';
  ctx.font = '11px sans-serif';
  ctx.fillText(`theta_i ${(thetaI * 180 / Math.PI).toFixed(1)} deg (${what}); luminance, 1/sr, log10`, 6, 13);
  lobes.forEach((l, j) => {
    ctx.fillStyle = colours[j % colours.length];
    ctx.fillText(l.label, 6, 28 + 13 * j);
  });
  document.getElementById('lobe-title').textContent = 'In-plane lobe (brdfkit plot)';
}

// Samples within settings.sample_tolerance degrees of the plane of incidence at theta_i:
// points at their theta_o (float32 rows: theta_h, theta_d, luminance, theta_i, theta_o,
// off-plane angle; degrees).
function drawLobeSamples(ctx, samples, thetaI, cx, cy, radius, lo, hi, settings, colours) {
  const ti = thetaI * 180 / Math.PI, tol = settings.sample_tolerance;
  (samples || []).forEach((s, j) => {
    if (!s.rows) return;
    ctx.fillStyle = colours[(j + 4) % colours.length];
    const r = s.rows;
    for (let i = 0; i < r.length; i += 6) {
      if (Math.abs(r[i + 3] - ti) > tol || r[i + 5] > tol) continue;
      const to = (r[i + 4] * Math.PI) / 180, rr = radius * logRadius(r[i + 2], lo, hi);
      ctx.beginPath();
      ctx.arc(cx + rr * Math.sin(to), cy - rr * Math.cos(to), 2.5, 0, 2 * Math.PI);
      ctx.fill();
    }
  });
}

function drawScale(canvas, top, display) {
  const ctx = canvas.getContext('2d'), w = canvas.width, h = canvas.height;
  for (let x = 0; x < w; x++) {
    ctx.fillStyle = inferno(x / (w - 1), display);
    ctx.fillRect(x, 0, 1, h);
  }
  const label = canvas.parentElement.querySelector('span') || document.createElement('span');
  label.textContent = `0 to ${top} (about 1: just noticeable)`;
  canvas.parentElement.appendChild(label);
}

// A sample file: its samples at (theta_d, theta_h) on the MERL grid's axes (theta_h on its
// square-root spacing), coloured by log10 luminance.
async function drawSamplePanels(root, samples, display) {
  for (const [j, s] of (samples || []).entries()) {
    s.rows = asFloat32(await blobBytes(s.points));
    const panel = document.createElement('div');
    panel.className = 'panel';
    const title = document.createElement('h2');
    title.textContent = `${s.label}: ${s.count} samples (theta_d across, theta_h up; log10 luminance)`;
    const canvas = document.createElement('canvas');
    canvas.width = 240;
    canvas.height = 240;
    panel.append(title, canvas);
    root.appendChild(panel);
    const ctx = canvas.getContext('2d'), r = s.rows, m = 14, size = 240 - 2 * m;
    let lo = Infinity, hi = -Infinity;
    for (let i = 0; i < r.length; i += 6) {
      if (r[i + 2] > 0) { lo = Math.min(lo, Math.log10(r[i + 2])); hi = Math.max(hi, Math.log10(r[i + 2])); }
    }
    ctx.strokeStyle = '#999';
    ctx.strokeRect(m, m, size, size);
    for (let i = 0; i < r.length; i += 6) {
      const x = m + size * r[i + 1] / 90, y = m + size * (1 - Math.sqrt(r[i] / 90));
      ctx.fillStyle = r[i + 2] > 0 ? inferno((Math.log10(r[i + 2]) - lo) / Math.max(hi - lo, 1e-6), display) : '#888';
      ctx.beginPath();
      ctx.arc(x, y, 2.5, 0, 2 * Math.PI);
      ctx.fill();
    }
    ctx.fillStyle = '#444';
    ctx.font = '10px sans-serif';
    ctx.fillText('theta_d 0-90', m, 240 - 2);
    ctx.fillText('theta_h', 2, 10);
  }
}
