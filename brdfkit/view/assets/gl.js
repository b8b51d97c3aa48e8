// WebGL2 helpers: programs assembled from the page's GLSL sources, textures, framebuffers.
'use strict';

// A program of the page: its fragment shader's source (brdfkit.view.page.glsl_program)
// after the page's header (brdfkit.view.page.GLSL_HEADER) and the defines.
function compileProgram(gl, header, source, defines) {
  const vs = '#version 300 es\nin vec2 a_pos;\nvoid main() { gl_Position = vec4(a_pos, 0.0, 1.0); }\n';
  const fs = header + Object.entries(defines || {}).map(([k, v]) => `#define ${k} ${v}\n`).join('') + source;
  const program = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const sh = gl.createShader(type);
    gl.shaderSource(sh, src);
    gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
      throw new Error('shader: ' + gl.getShaderInfoLog(sh));
    }
    gl.attachShader(program, sh);
  }
  gl.bindAttribLocation(program, 0, 'a_pos');
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(program));
  const uniforms = {}, types = {};
  const n = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < n; i++) {
    const info = gl.getActiveUniform(program, i);
    const name = info.name.replace(/\[0\]$/, '');
    uniforms[name] = gl.getUniformLocation(program, info.name);
    types[name] = info.type;
  }
  return { program, uniforms, types };
}

// Uniforms brdfkit wrote into the page, by name: a number or the flat values of a vector,
// matrix or array, set as the program declares it (a name it does not use is left out, as
// a compiler leaves out what a shader does not read).
function setUniforms(gl, p, values) {
  const setters = {
    [gl.FLOAT]: (l, v) => gl.uniform1fv(l, v), [gl.FLOAT_VEC2]: (l, v) => gl.uniform2fv(l, v),
    [gl.FLOAT_VEC3]: (l, v) => gl.uniform3fv(l, v), [gl.FLOAT_VEC4]: (l, v) => gl.uniform4fv(l, v),
    [gl.INT]: (l, v) => gl.uniform1iv(l, v), [gl.INT_VEC3]: (l, v) => gl.uniform3iv(l, v),
    [gl.FLOAT_MAT3]: (l, v) => gl.uniformMatrix3fv(l, false, v),
  };
  for (const [name, value] of Object.entries(values)) {
    if (!(name in p.uniforms)) continue;
    const set = setters[p.types[name]];
    if (!set) throw new Error(`uniform ${name}: a type the page does not set`);
    const flat = Array.isArray(value) ? value : [value];
    set(p.uniforms[name], p.types[name] === gl.INT || p.types[name] === gl.INT_VEC3 ? Int32Array.from(flat) : Float32Array.from(flat));
  }
}

function fullScreenTriangle(gl) {
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buf = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  return vao;
}

function texture2D(gl, internal, format, type, width, height, data) {
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, internal, width, height, 0, format, type, data);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
  return tex;
}

function texture3D(gl, internal, format, type, data) {
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_3D, tex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage3D(gl.TEXTURE_3D, 0, internal, 180, 90, 90, 0, format, type, data);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_3D, p, gl.NEAREST);
  for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T, gl.TEXTURE_WRAP_R]) {
    gl.texParameteri(gl.TEXTURE_3D, p, gl.CLAMP_TO_EDGE);
  }
  return tex;
}

function floatTarget(gl, width, height) {
  const tex = texture2D(gl, gl.RGBA32F, gl.RGBA, gl.FLOAT, width, height, null);
  const fbo = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) {
    throw new Error('this browser cannot render to float textures (WebGL2 EXT_color_buffer_float)');
  }
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  return { tex, fbo, width, height };
}

function bindTexture(gl, unit, target, tex, location) {
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(target, tex);
  if (location) gl.uniform1i(location, unit);
}

// The next frame, or 16 ms, whichever comes first: a page that no one shows (Chromium's
// own --headless --screenshot) runs no animation frames, but its timers run.
function nextFrame() {
  return new Promise((resolve) => {
    requestAnimationFrame(() => resolve());
    setTimeout(resolve, 16);
  });
}
