// Live embeddings (brdfkit view --live): the basis as textures and the decode on the GPU
// (brdfkit_decode.glsl, with the defines and uniforms brdfkit wrote for each material),
// baked into the table texture that brdfkit_eval reads.
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
  // bases: the page's basis records (brdfkit.view.live.basis_data); program(defines): the
  // bake shader compiled with a material's defines.
  constructor(gl, bases, program, vao) {
    this.gl = gl;
    this.records = bases;
    this.compile = program;
    this.vao = vao;
    this.bases = new Map();
    this.programs = new Map();
  }

  // The basis's slots over its cells, in slot order (reference, mean, components).
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

  // The basis's textures: texture t holds the slots b.layout[t], each b.fill off the cells
  // (brdfkit.view.live.basis_textures).
  async basis(index) {
    if (this.bases.has(index)) return this.bases.get(index);
    const gl = this.gl, b = this.records[index];
    const { cells, arrays } = await this.slots(b);
    const textures = b.layout.map((slots) => {
      const texels = new Float32Array(CELLS * 4);
      slots.forEach((s, channel) => {
        if (b.fill[s] !== 0) for (let i = 0; i < CELLS; i++) texels[4 * i + channel] = b.fill[s];
        cells.forEach((c, j) => { texels[4 * c + channel] = arrays[s][j]; });
      });
      return texture3D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, texels);
    });
    this.bases.set(index, textures);
    return textures;
  }

  program(defines) {
    const key = JSON.stringify(defines);
    if (!this.programs.has(key)) this.programs.set(key, this.compile(defines));
    return this.programs.get(key);
  }

  // The material's table, decoded by brdfkit_decode.glsl with the defines and uniforms
  // brdfkit wrote for it (brdfkit.view.live.material_uniforms), one channel a pass.
  async bake(m) {
    const gl = this.gl, textures = await this.basis(m.basis);
    const p = this.program(m.defines), u = p.uniforms, count = m.defines.BRDFKIT_TEXTURES;
    const tex = texture3D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, null);
    const fbo = gl.createFramebuffer();
    gl.useProgram(p.program);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.viewport(0, 0, 180, 90);
    textures.slice(0, count).forEach((t, i) => bindTexture(gl, i, gl.TEXTURE_3D, t));
    gl.uniform1iv(u.brdfkit_basis, Int32Array.from({ length: count }, (_, i) => i));
    setUniforms(gl, p, m.uniforms);
    for (let ch = 0; ch < 3; ch++) {
      setUniforms(gl, p, m.channels[ch]);
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
