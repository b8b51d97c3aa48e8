// Live embeddings (brdfkit view --live): the basis as textures, the residual's
// hypernetwork in JavaScript (3K numbers -> the hyponet's weights, one channel at a time)
// and the decode on the GPU (brdfkit_decode.glsl), baked into the table texture that
// brdfkit_eval reads.
'use strict';

const CELLS = 90 * 90 * 180;

function unpackBits(bytes) {
  const out = new Uint8Array(CELLS);
  for (let i = 0; i < CELLS; i++) out[i] = (bytes[i >> 3] >> (7 - (i & 7))) & 1;
  return out;
}

// The basis's slots (reference, mean, U_0 ...) over the grid, as brdfkit.basis.storage.expand
// restores a half-phi_d basis: a stored cell as stored, another (odd phi_d) cell the mean of
// its two stored even neighbours, or the one of them that is stored.
class BasisSlots {
  constructor(b, stored, cellMask) {
    this.b = b;
    this.cells = [];
    for (let i = 0; i < CELLS; i++) if (cellMask[i]) this.cells.push(i);
    this.storedPos = new Int32Array(CELLS).fill(-1);
    let n = 0;
    for (let i = 0; i < CELLS; i++) if (stored[i]) this.storedPos[i] = n++;
    this.count = n;
  }

  expand(values) {
    const out = new Float32Array(this.cells.length), pos = this.storedPos;
    this.cells.forEach((c, j) => {
      const own = pos[c];
      if (own >= 0) { out[j] = values[own]; return; }
      const p = c % 180, row = c - p, left = pos[row + p - 1], right = pos[row + (p + 1) % 180];
      out[j] = left >= 0 && right >= 0 ? Math.fround(Math.fround(values[left] * 0.5) + Math.fround(values[right] * 0.5))
        : values[left >= 0 ? left : right];
    });
    return out;
  }
}

class LiveDecoder {
  constructor(gl, live, shaders, vao) {
    this.gl = gl;
    this.live = live;
    this.shaders = shaders;
    this.vao = vao;
    this.bases = new Map();
    this.programs = new Map();
    this.nets = new Map();
  }

  async slots(b) {
    const arrays = [];
    const half = async (blob) => Float32Array.from(asUint16(await blobBytes(blob)), halfToFloat);
    if (b.storage === 'compact') {
      const slots = new BasisSlots(b, unpackBits(await blobBytes(b.stored_mask)), unpackBits(await blobBytes(b.cell_mask)));
      arrays.push(slots.expand(await half(b.reference)), slots.expand(await half(b.mean)));
      const q = asInt8(await blobBytes(b.components)), scales = asFloat32(await blobBytes(b.scales));
      const nb = Math.ceil(slots.count / b.block), row = new Float32Array(slots.count);
      for (let k = 0; k < b.k; k++) {
        for (let i = 0; i < slots.count; i++) row[i] = Math.fround(q[k * slots.count + i] * scales[k * nb + Math.floor(i / b.block)]);
        arrays.push(slots.expand(row));
      }
      return { cells: slots.cells, arrays };
    }
    const cellMask = unpackBits(await blobBytes(b.cell_mask)), cells = [];
    for (let i = 0; i < CELLS; i++) if (cellMask[i]) cells.push(i);
    const all = asFloat32(await blobBytes(b.values));  // (K + 2, P): reference, mean, components
    for (let s = 0; s < b.k + 2; s++) arrays.push(all.subarray(s * cells.length, (s + 1) * cells.length));
    return { cells, arrays };
  }

  async basis(index) {
    if (this.bases.has(index)) return this.bases.get(index);
    const gl = this.gl, b = this.live.bases[index];
    const { cells, arrays } = await this.slots(b);
    const count = Math.ceil((b.k + 2) / 4), textures = [];
    for (let t = 0; t < count; t++) {
      const texels = new Float32Array(CELLS * 4);
      if (t === 0) for (let i = 0; i < CELLS; i++) texels[4 * i] = -1;
      for (let s = 4 * t; s < Math.min(4 * t + 4, b.k + 2); s++) {
        const a = arrays[s];
        cells.forEach((c, j) => { texels[4 * c + (s - 4 * t)] = a[j]; });
      }
      textures.push(texture3D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, texels));
    }
    const out = { b, textures };
    this.bases.set(index, out);
    return out;
  }

  // The hyponet's weights for one channel's coefficients in training standard deviations
  // (brdfkit.residual.network.net_input and hyponet_weights), packed as brdfkit_net.
  async hyponet(index, cNorm) {
    const n = this.live.nets[index];
    if (!this.nets.has(index)) {
      const t = {};
      for (const [name, blob] of Object.entries(n.tensors)) t[name] = asFloat32(await blobBytes(blob));
      this.nets.set(index, t);
    }
    const t = this.nets.get(index), kmax = n.k_max, hidden = n.hidden, w = n.width;
    const z = new Float64Array(2 * kmax);
    cNorm.forEach((c, i) => { z[i] = c; z[kmax + i] = 1; });
    const layer = (weight, bias, x, rows, cols) => {
      const y = new Float64Array(rows);
      for (let r = 0; r < rows; r++) {
        let a = bias[r];
        for (let c = 0; c < cols; c++) a += weight[r * cols + c] * x[c];
        y[r] = Math.max(a, 0);
      }
      return y;
    };
    const h = layer(t['body.2.weight'], t['body.2.bias'], layer(t['body.0.weight'], t['body.0.bias'], z, hidden, 2 * kmax), hidden, hidden);
    const total = t['head.bias'].length, flat = new Float64Array(total), head = t['head.weight'];
    for (let r = 0; r < total; r++) {
      let a = t['head.bias'][r];
      for (let c = 0; c < hidden; c++) a += head[r * hidden + c] * h[c];
      flat[r] = a;
    }
    const parts = [], sizes = [6 * w, w, w * w, w, w, 1];
    let at = 0;
    sizes.forEach((size, i) => {
      const base = t[`base.${i}`];
      parts.push(Float64Array.from(base, (v, j) => v + flat[at + j]));
      at += size;
    });
    return packHyponet(parts, w);
  }

  program(textures, width) {
    const key = `${textures}/${width}`;
    if (!this.programs.has(key)) {
      this.programs.set(key, compileProgram(this.gl, [this.shaders.decode, this.shaders.bake],
        { BRDFKIT_TEXTURES: textures, BRDFKIT_WIDTH: width }));
    }
    return this.programs.get(key);
  }

  async bake(m) {
    const gl = this.gl, base = await this.basis(m.basis), b = base.b, k = m.k;
    const net = m.net === null ? null : this.live.nets[m.net];
    const width = net ? 4 * Math.ceil(net.width / 4) : 0;
    const p = this.program(base.textures.length, width), u = p.uniforms;
    const tex = texture3D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, null);
    const fbo = gl.createFramebuffer();
    gl.useProgram(p.program);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.viewport(0, 0, 180, 90);
    base.textures.forEach((t, i) => bindTexture(gl, i, gl.TEXTURE_3D, t, u[`brdfkit_basis${i}`]));
    gl.uniform4f(u.brdfkit_mapping, b.eps, b.floor, b.cap, b.w_floor);
    gl.uniform2f(u.brdfkit_tiny, b.tiny, b.w_tiny);
    gl.uniform1f(u.brdfkit_gain, net ? m.gain : 0.0);
    for (let ch = 0; ch < 3; ch++) {
      const coef = new Float32Array(4 * base.textures.length);
      coef[1] = 1;
      for (let j = 0; j < k; j++) coef[2 + j] = m.coefficients[3 * j + ch];
      gl.uniform4fv(u.brdfkit_coefficients, coef);
      if (net && m.gain !== 0) {
        const cNorm = [];
        for (let j = 0; j < k; j++) cNorm.push(m.coefficients[3 * j + ch] / b.sigma[j]);
        gl.uniform4fv(u.brdfkit_net, await this.hyponet(m.net, cNorm));
      }
      gl.colorMask(ch === 0, ch === 1, ch === 2, false);
      for (let layer = 0; layer < 90; layer++) {
        gl.framebufferTextureLayer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, tex, 0, layer);
        gl.uniform1i(u.u_layer, layer);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
        if (layer % 15 === 14) await nextFrame();
      }
    }
    gl.colorMask(true, true, true, true);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fbo);
    return tex;
  }
}

// brdfkit_net's layout: w1 (6 rows of W), b1, w2 (W rows of W), b2, w3, b3, each row padded
// to a multiple of 4 (the padding's weights 0).
function packHyponet([w1, b1, w2, b2, w3, b3], w) {
  const w4 = Math.ceil(w / 4), wp = 4 * w4;
  const out = new Float32Array(4 * (9 * w4 + wp * w4 + 1));
  const row = (src, off, at) => { for (let j = 0; j < w; j++) out[at + j] = src[off + j]; };
  for (let i = 0; i < 6; i++) row(w1, i * w, 4 * i * w4);
  row(b1, 0, 4 * 6 * w4);
  for (let i = 0; i < w; i++) row(w2, i * w, 4 * (7 * w4 + i * w4));
  row(b2, 0, 4 * (7 * w4 + wp * w4));
  row(w3, 0, 4 * (8 * w4 + wp * w4));
  out[4 * (9 * w4 + wp * w4)] = b3[0];
  return out;
}
