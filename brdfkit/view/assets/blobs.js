// The page's binary blobs (brdfkit.view.textures.blob): base64, gzip unless written with
// --no-compress (decompressed by the browser's own DecompressionStream), float16 arrays
// split into byte planes.
'use strict';

async function blobBytes(b) {
  // atob, not fetch of a data: URL: a fetch waits on the network stack, which Chromium's own
  // --screenshot (with --virtual-time-budget) does not wait for.
  let raw = base64Bytes(b.data);
  if (b.enc === 'gzip') {
    if (typeof DecompressionStream === 'undefined') {
      throw new Error('this browser has no DecompressionStream: write the page with brdfkit view --no-compress');
    }
    const stream = new Blob([raw]).stream().pipeThrough(new DecompressionStream('gzip'));
    raw = new Uint8Array(await new Response(stream).arrayBuffer());
  }
  if (raw.length !== b.bytes) throw new Error('a data blob of the page is damaged');
  if (!b.planes) return raw;
  const n = raw.length >> 1, out = new Uint8Array(raw.length);
  for (let i = 0; i < n; i++) {
    out[2 * i] = raw[i];
    out[2 * i + 1] = raw[n + i];
  }
  return out;
}

function base64Bytes(text) {
  const s = atob(text), out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

function asFloat32(bytes) { return new Float32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength >> 2); }
function asUint16(bytes) { return new Uint16Array(bytes.buffer, bytes.byteOffset, bytes.byteLength >> 1); }
function asInt8(bytes) { return new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength); }

function halfToFloat(h) {
  const s = (h & 0x8000) ? -1 : 1, e = (h >> 10) & 0x1f, m = h & 0x3ff;
  if (e === 0) return s * m * Math.pow(2, -24);
  if (e === 31) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * Math.pow(2, e - 15);
}
