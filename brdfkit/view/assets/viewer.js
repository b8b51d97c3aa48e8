// brdfkit view: the page's application. Reads the data brdfkit wrote into the page,
// uploads the tables (or decodes live embeddings on the GPU, live.js), renders every
// material on the reference scene's sphere (render.frag) and shows them (display.frag),
// with the lobe plot and the sample files' points (plots.js).
'use strict';

const GAP = 8;

function hashOptions() {
  const out = {};
  for (const part of location.hash.replace(/^#/, '').split('&')) {
    if (!part) continue;
    const [k, v] = part.split('=');
    out[decodeURIComponent(k)] = v === undefined ? '' : decodeURIComponent(v);
  }
  return out;
}

function say(text, error) {
  const el = document.getElementById('message');
  el.textContent = text;
  el.className = error ? 'error' : '';
}

async function loadScene(gl, s) {
  const nodes = asFloat32(await blobBytes(s.nodes));
  const env = asFloat32(await blobBytes(s.env));
  return {
    nodes: texture2D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, s.node_width, 6, nodes),
    env: texture2D(gl, gl.RGB32F, gl.RGB, gl.FLOAT, s.env_size[0], s.env_size[1], env),
    data: s,
  };
}

function setSceneUniforms(gl, p, scene, size) {
  bindTexture(gl, 1, gl.TEXTURE_2D, scene.nodes, p.uniforms.u_nodes);
  bindTexture(gl, 2, gl.TEXTURE_2D, scene.env, p.uniforms.u_env);
  setUniforms(gl, p, scene.data.uniforms);
  gl.uniform1f(p.uniforms.u_size, size);
}

class Viewer {
  constructor(gl, data, shaders, opts) {
    this.gl = gl;
    this.data = data;
    this.shaders = shaders;
    this.opts = opts;
    this.still = opts.still !== undefined;
    this.size = Math.max(16, Math.min(2048, parseInt(opts.size || data.scene.resolution, 10) || 256));
    this.exposure = Math.pow(2, parseFloat(opts.exposure || '0') || 0);
    this.lightMode = opts.light === 'directional' ? 1 : 0;
    this.light = this.parseLight(opts.dir);
    this.difference = opts.view === 'difference';
    this.deMax = parseFloat(opts.scale || '5') || 5;
    this.vao = fullScreenTriangle(gl);
    this.materials = [];
    this.generation = 0;
  }

  parseLight(text) {
    const v = (text || '').split(',').map(Number);
    if (v.length === 3 && v.every(Number.isFinite) && Math.hypot(...v) > 0) {
      const n = Math.hypot(...v);
      return v.map((x) => x / n);
    }
    return [0.0, 0.0, 1.0];
  }

  async load() {
    const gl = this.gl, d = this.data;
    this.scene = await loadScene(gl, d.scene);
    const program = (name, defines) => compileProgram(gl, this.shaders.header, this.shaders.programs[name], defines);
    this.render = program('render', d.scene.defines);
    this.probe = program('probe');
    this.display = program('display');
    const lut = d.display.inferno;
    this.inferno = texture2D(gl, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, lut.length / 4, 1, Uint8Array.from(lut));
    const wanted = this.wantedMaterials();
    const live = this.live = d.bases ? new LiveDecoder(gl, d.bases, (defines) => program('bake', defines), this.vao) : null;
    for (const [i, m] of d.materials.entries()) {
      if (!wanted.has(i)) { this.materials.push(null); continue; }
      say(`loading ${m.label} (${i + 1} of ${d.materials.length})`);
      let tex, scale = 1.0;
      if (m.kind === 'live') {
        tex = await live.bake(m);
      } else {
        tex = texture3D(gl, gl.RGB16F, gl.RGB, gl.HALF_FLOAT, asUint16(await blobBytes(m.table)));
        scale = m.scale;
      }
      this.materials.push({ info: m, tex, scale, target: floatTarget(gl, this.size, this.size), index: i });
    }
    this.probeTarget = floatTarget(gl, d.lobe.theta_o.length, 1);
  }

  wantedMaterials() {
    const n = this.data.materials.length, all = new Set([...Array(n).keys()]);
    if (!this.still) return all;
    const s = this.opts.still;
    const k = s === 'reference' || s === '' ? 0 : parseInt(s, 10) - 1;
    if (!(k >= 0 && k < n)) throw new Error(`#still=${s}: this page has materials 1 to ${n} (1: the reference)`);
    this.stillIndex = k;
    return this.difference ? new Set([0, k]) : new Set([k]);
  }

  tiles() {
    if (this.still) return [{ m: this.materials[this.stillIndex], x: 0, row: 0 }];
    return this.materials.filter(Boolean).map((m, i) => ({ m, x: i * (this.size + GAP), row: 0 }));
  }

  layout() {
    const tiles = this.tiles(), size = this.size, canvas = this.gl.canvas;
    const rows = !this.still && this.difference && tiles.length > 1 ? 2 : 1;
    const width = this.still ? size : tiles.length * size + (tiles.length - 1) * GAP;
    const height = rows * size + (rows - 1) * GAP;
    if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width;
      canvas.height = height;
    }
    return { tiles, rows, width, height };
  }

  drawTile(m, y0, y1) {
    const gl = this.gl, p = this.render, u = p.uniforms;
    gl.useProgram(p.program);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, m.target.fbo);
    gl.viewport(0, 0, this.size, this.size);
    gl.enable(gl.SCISSOR_TEST);
    gl.scissor(0, y0, this.size, y1 - y0);
    setSceneUniforms(gl, p, this.scene, this.size);
    bindTexture(gl, 0, gl.TEXTURE_3D, m.tex, u.brdfkit_table);
    gl.uniform1f(u.brdfkit_scale, m.scale);
    gl.uniform2f(u.u_origin, 0, 0);
    gl.uniform1i(u.u_light_mode, this.lightMode);
    gl.uniform3f(u.u_light, ...this.light);
    gl.uniform1f(u.u_irradiance, Math.PI);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.disable(gl.SCISSOR_TEST);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  }

  async renderAll() {
    // In a still of the difference view the reference is drawn too, though not shown.
    const generation = ++this.generation, tiles = this.materials.filter(Boolean).map((m) => ({ m }));
    const t0 = performance.now();
    // The environment costs hundreds of BRDF lookups a pixel: drawn in bands, a frame
    // each, so that a software renderer stays responsive and no draw runs for long.
    const band = this.lightMode === 0 ? Math.max(1, Math.round(8192 / this.size)) : this.size;
    for (const [i, t] of tiles.entries()) {
      for (let y = 0; y < this.size; y += band) {
        if (generation !== this.generation) return false;
        this.drawTile(t.m, y, Math.min(this.size, y + band));
        if (!this.still) {
          this.composite();
          say(`rendering ${t.m.info.label} (${i + 1} of ${tiles.length}): ${Math.round(100 * (y + band) / this.size)}%`);
        }
        if (this.lightMode === 0) await nextFrame();
      }
    }
    this.composite();
    this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, new Uint8Array(4));  // the draws done
    if (!this.still) {
      const what = this.lightMode === 0 ? 'the reference scene\'s environment, the quadrature of brdfkit render'
        : 'a directional light';
      say(`${tiles.length} material(s) lit by ${what}: ${Math.round(performance.now() - t0)} ms`);
      this.updateLobe();
    }
    return true;
  }

  composite() {
    const gl = this.gl, p = this.display, u = p.uniforms, size = this.size;
    const { tiles, rows, height } = this.layout();
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, gl.canvas.width, gl.canvas.height);
    gl.clearColor(0.067, 0.067, 0.067, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(p.program);
    gl.bindVertexArray(this.vao);
    gl.uniform1f(u.u_exposure, this.exposure * this.data.display.exposure);
    gl.uniform1f(u.u_de_max, this.deMax);
    setUniforms(gl, p, this.data.display.uniforms);
    bindTexture(gl, 2, gl.TEXTURE_2D, this.inferno, u.u_inferno);
    const ref = this.materials[0] || tiles[0].m;
    const draw = (m, x, y, view) => {
      gl.viewport(x, y, size, size);
      gl.uniform2f(u.u_origin, x, y);
      gl.uniform1i(u.u_view, view);
      bindTexture(gl, 0, gl.TEXTURE_2D, m.target.tex, u.u_image);
      bindTexture(gl, 1, gl.TEXTURE_2D, ref.target.tex, u.u_reference);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    };
    const stillDifference = this.still && this.difference;
    for (const t of tiles) draw(t.m, t.x, height - size, stillDifference ? 1 : 0);
    if (rows === 2) tiles.slice(1).forEach((t) => draw(t.m, t.x, 0, 1));
    this.placeCaptions(tiles, rows);
  }

  placeCaptions(tiles, rows) {
    if (this.still) return;
    const stage = document.getElementById('stage');
    stage.querySelectorAll('.caption').forEach((e) => e.remove());
    const add = (text, x, y) => {
      const el = document.createElement('div');
      el.className = 'caption';
      el.textContent = text;
      el.style.left = x + 'px';
      el.style.top = y + 'px';
      stage.appendChild(el);
    };
    tiles.forEach((t, i) => add((i === 0 ? 'reference: ' : '') + t.m.info.label + (t.m.info.kind === 'live' ? ' (live)' : ''), t.x, 0));
    if (rows === 2) tiles.slice(1).forEach((t) => add(`Delta E 2000: ${t.m.info.label}`, t.x, this.size + GAP));
    document.getElementById('scale-panel').hidden = rows !== 2;
  }

  lobeValues(thetaI) {
    const gl = this.gl, p = this.probe, u = p.uniforms, out = [], lobe = this.data.lobe;
    const n = lobe.theta_o.length, y = lobe.luminance;
    gl.useProgram(p.program);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.probeTarget.fbo);
    gl.viewport(0, 0, n, 1);
    gl.uniform1f(u.u_theta_i, thetaI);
    setUniforms(gl, p, lobe.uniforms);
    const px = new Float32Array(n * 4);
    for (const m of this.materials.filter(Boolean)) {
      bindTexture(gl, 0, gl.TEXTURE_3D, m.tex, u.brdfkit_table);
      gl.uniform1f(u.brdfkit_scale, m.scale);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      gl.readPixels(0, 0, n, 1, gl.RGBA, gl.FLOAT, px);
      const lum = new Float64Array(n);
      for (let i = 0; i < n; i++) lum[i] = y[0] * px[4 * i] + y[1] * px[4 * i + 1] + y[2] * px[4 * i + 2];
      out.push({ label: m.info.label, values: lum });
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    return out;
  }

  thetaI() {
    const d = this.lightMode === 1 ? this.light : this.data.scene.sun;
    return Math.acos(Math.max(-1, Math.min(1, d[2])));
  }

  updateLobe() {
    const ti = Math.min(this.thetaI(), (89.5 * Math.PI) / 180);
    const what = this.lightMode === 1 ? 'the light' : 'the sun';
    drawLobe(document.getElementById('lobe'), this.lobeValues(ti), ti, what, this.data.samples, this.data.lobe,
             this.data.display);
  }

  pointerLight(ev) {
    const canvas = this.gl.canvas, size = this.size;
    const x = (ev.offsetX * canvas.width) / canvas.clientWidth;
    const y = (ev.offsetY * canvas.height) / canvas.clientHeight;
    if (y >= size) return null;
    const lx = x - Math.floor(x / (size + GAP)) * (size + GAP);
    if (lx >= size) return null;
    const vhw = this.data.scene.uniforms.u_view_half_width;
    const px = (lx / size * 2 - 1) * vhw, py = -(y / size * 2 - 1) * vhw, r2 = px * px + py * py;
    if (r2 < 1) return [px, py, Math.sqrt(1 - r2)];
    const r = Math.sqrt(r2);
    return [px / r, py / r, 0.0];
  }
}

function wireControls(v) {
  const radios = document.querySelectorAll('input[name=light]');
  const setMode = (mode) => {
    v.lightMode = mode;
    radios.forEach((r) => { r.checked = (r.value === 'directional') === (mode === 1); });
    v.renderAll();
  };
  radios.forEach((r) => r.addEventListener('change', () => setMode(r.value === 'directional' ? 1 : 0)));
  const exposure = document.getElementById('exposure'), out = document.getElementById('exposure-out');
  exposure.addEventListener('input', () => {
    v.exposure = Math.pow(2, parseFloat(exposure.value));
    out.textContent = `${parseFloat(exposure.value).toFixed(1)} EV`;
    v.composite();
  });
  const diff = document.getElementById('difference'), deMax = document.getElementById('de-max');
  const redraw = () => {
    v.difference = diff.checked;
    v.deMax = parseFloat(deMax.value);
    drawScale(document.getElementById('scale-bar'), v.deMax, v.data.display);
    v.composite();
  };
  diff.addEventListener('change', redraw);
  deMax.addEventListener('change', redraw);
  drawScale(document.getElementById('scale-bar'), v.deMax, v.data.display);
  const canvas = v.gl.canvas;
  let dragging = false;
  const move = (ev) => {
    const l = v.pointerLight(ev);
    if (!l) return;
    v.light = l;
    if (v.lightMode !== 1) setMode(1); else v.renderAll();
  };
  canvas.addEventListener('pointerdown', (ev) => { dragging = true; canvas.setPointerCapture(ev.pointerId); move(ev); });
  canvas.addEventListener('pointermove', (ev) => { if (dragging) move(ev); });
  canvas.addEventListener('pointerup', () => { dragging = false; });
  window.addEventListener('hashchange', () => location.reload());
}

async function main() {
  const data = JSON.parse(document.getElementById('brdfkit-data').textContent);
  const shaders = JSON.parse(document.getElementById('brdfkit-shaders').textContent);
  const opts = hashOptions();
  const v0 = opts.still !== undefined;
  if (v0) document.body.className = 'still';
  const canvas = document.getElementById('gl');
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: false, depth: false, premultipliedAlpha: false,
                                           preserveDrawingBuffer: true });
  if (!gl) throw new Error('this browser has no WebGL2');
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('this browser cannot render to float textures (EXT_color_buffer_float)');
  const v = new Viewer(gl, data, shaders, opts);
  window.brdfkitViewer = v;
  const t0 = performance.now();
  await v.load();
  const t1 = performance.now();
  if (!v.still) {
    wireControls(v);
    await drawSamplePanels(document.getElementById('samples'), data.samples, data.display);
  }
  await v.renderAll();
  window.brdfkitTimes = { load: t1 - t0, render: performance.now() - t1 };
  await nextFrame();
  await nextFrame();
  if (v.still) document.title = 'ready';
  document.body.dataset.state = 'ready';
}

main().catch((e) => {
  document.title = 'error';
  say(String(e && e.message ? e.message : e), true);
  window.brdfkitError = String(e && e.stack ? e.stack : e);
});
