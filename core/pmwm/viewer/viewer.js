/* pmwm viewer: streams a .pmwm progressive mesh and draws it level by level (plain WebGL 2, no library).

The .pmwm file (little endian; pmwm.pmfile): a 32-byte header (magic, version u16, flags u16 with bit 0
for float64 positions, base vertices, base faces, records, levels, reserved: u32 each), the base
vertices, the base faces (u32 x 3), the level table (records at the end of each level, u32), the
records (position, v u32 with the split flags in its top two bits, mask u64) and the SHA-256 of
everything before it. Record r adds vertex u = nb + r at its position, moves the faces of v whose rank
among v's faces (in face order) is set in the mask to u, and appends [u, v, p] and/or [u, q, v], p and
q the ends of the moved arc of faces. Decoding here applies the records one by one, exactly as
`pmwm decode` does: the same vertices and faces in the same order at every level.

"Level K" counts records, as `pmwm decode --level K` does; the file's own levels (batches of records)
are the places where the mesh is drawn while it streams, and the slider's stops.
*/
(function () {
  "use strict";

  // ------------------------------------------------------------------ SHA-256 (incremental)

  const K256 = new Int32Array([
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2,
  ]);

  class Sha256 {
    constructor() {
      this.h = new Int32Array([
        0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19,
      ]);
      this.buf = new Uint8Array(64);
      this.fill = 0;
      this.length = 0;
      this.w = new Int32Array(64);
    }

    update(data) {
      let i = 0;
      const n = data.length;
      this.length += n;
      if (this.fill) {
        const t = Math.min(64 - this.fill, n);
        this.buf.set(data.subarray(0, t), this.fill);
        this.fill += t;
        i = t;
        if (this.fill < 64) return;
        this.block(this.buf, 0);
        this.fill = 0;
      }
      for (; i + 64 <= n; i += 64) this.block(data, i);
      if (i < n) {
        this.buf.set(data.subarray(i), 0);
        this.fill = n - i;
      }
    }

    block(d, o) {
      const w = this.w;
      for (let t = 0; t < 16; t++) {
        const j = o + 4 * t;
        w[t] = (d[j] << 24) | (d[j + 1] << 16) | (d[j + 2] << 8) | d[j + 3];
      }
      for (let t = 16; t < 64; t++) {
        const a = w[t - 15];
        const b = w[t - 2];
        const s0 = ((a >>> 7) | (a << 25)) ^ ((a >>> 18) | (a << 14)) ^ (a >>> 3);
        const s1 = ((b >>> 17) | (b << 15)) ^ ((b >>> 19) | (b << 13)) ^ (b >>> 10);
        w[t] = (w[t - 16] + s0 + w[t - 7] + s1) | 0;
      }
      const H = this.h;
      let a = H[0], b = H[1], c = H[2], e = H[4], f = H[5], g = H[6], h = H[7], dd = H[3];
      for (let t = 0; t < 64; t++) {
        const S1 = ((e >>> 6) | (e << 26)) ^ ((e >>> 11) | (e << 21)) ^ ((e >>> 25) | (e << 7));
        const t1 = (h + S1 + ((e & f) ^ (~e & g)) + K256[t] + w[t]) | 0;
        const S0 = ((a >>> 2) | (a << 30)) ^ ((a >>> 13) | (a << 19)) ^ ((a >>> 22) | (a << 10));
        const t2 = (S0 + ((a & b) ^ (a & c) ^ (b & c))) | 0;
        h = g; g = f; f = e; e = (dd + t1) | 0; dd = c; c = b; b = a; a = (t1 + t2) | 0;
      }
      H[0] = (H[0] + a) | 0; H[1] = (H[1] + b) | 0; H[2] = (H[2] + c) | 0; H[3] = (H[3] + dd) | 0;
      H[4] = (H[4] + e) | 0; H[5] = (H[5] + f) | 0; H[6] = (H[6] + g) | 0; H[7] = (H[7] + h) | 0;
    }

    digest() {
      const bits = this.length * 8;
      const pad = new Uint8Array(((this.fill < 56 ? 56 : 120) - this.fill) + 8);
      pad[0] = 0x80;
      const hi = Math.floor(bits / 4294967296);
      const lo = bits >>> 0;
      const e = pad.length;
      pad[e - 8] = hi >>> 24; pad[e - 7] = hi >>> 16; pad[e - 6] = hi >>> 8; pad[e - 5] = hi;
      pad[e - 4] = lo >>> 24; pad[e - 3] = lo >>> 16; pad[e - 2] = lo >>> 8; pad[e - 1] = lo;
      this.update(pad);
      const out = new Uint8Array(32);
      for (let i = 0; i < 8; i++) {
        out[4 * i] = this.h[i] >>> 24; out[4 * i + 1] = this.h[i] >>> 16;
        out[4 * i + 2] = this.h[i] >>> 8; out[4 * i + 3] = this.h[i];
      }
      return out;
    }
  }

  const hex = (bytes) => Array.from(bytes, (x) => x.toString(16).padStart(2, "0")).join("");

  // ------------------------------------------------------------------ the file format

  const MAGIC = [0x89, 0x50, 0x4d, 0x57, 0x4d, 0x0d, 0x0a, 0x1a];
  const HEADER = 32;
  const DIGEST = 32;
  const VERSION = 2;
  const FLAG_F64 = 1;
  const FLAG_SINGLE = 1; // the split adds one face (boundary)
  const FLAG_SECOND = 2; // ... the one holding the half-edge v -> u
  const ENDS_SHIFT = 52; // the mask's top 12 bits name the arc's end faces (version 2, v of at most 52 faces)
  const NO_END = 63;
  const MAX_BYTES = 256e6; // the largest file the page takes (its arrays take about three times that)
  const NEXT = [1, 2, 0]; // a face's next corner, by corner
  const PREV = [2, 0, 1];
  const LITTLE = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

  class PmError extends Error {
    constructor(kind, message) {
      super(message);
      this.kind = kind; // "format", "corrupted", "truncated", "network", "usage"
    }
  }

  const corrupted = (what) =>
    new PmError("corrupted", `The model file is corrupted (${what}); it was damaged on the way or not written by pmwm.`);

  /** The header's numbers and the file's layout; PmError when they cannot be a .pmwm file. */
  function parseHeader(b) {
    for (let i = 0; i < 8; i++) {
      if (b[i] !== MAGIC[i]) throw new PmError("format", "This is not a .pmwm progressive mesh (wrong magic bytes).");
    }
    const dv = new DataView(b.buffer, b.byteOffset, HEADER);
    const version = dv.getUint16(8, true);
    const flags = dv.getUint16(10, true);
    if (version < 1 || version > VERSION) {
      throw new PmError("format", `The model is .pmwm version ${version}; this page reads versions 1 to ${VERSION}: ` +
        "publish it again with this pmwm.");
    }
    if (flags & ~FLAG_F64) throw new PmError("format", `The model uses unknown .pmwm flags (${flags}): publish it again.`);
    const h = {
      version, f64: (flags & FLAG_F64) !== 0,
      nb: dv.getUint32(12, true), fb: dv.getUint32(16, true), nr: dv.getUint32(20, true), nl: dv.getUint32(24, true),
    };
    h.fsize = h.f64 ? 8 : 4;
    h.rsize = 3 * h.fsize + 12;
    h.facesAt = HEADER + h.nb * 3 * h.fsize;
    h.levelsAt = h.facesAt + h.fb * 12;
    h.recordsAt = h.levelsAt + h.nl * 4;
    h.total = h.recordsAt + h.nr * h.rsize + DIGEST;
    if (h.nb + h.nr >= 2 ** 30 || h.total > 2 ** 31) throw corrupted("its header promises an impossible size");
    if (h.total > MAX_BYTES) {
      throw new PmError("format", `The model is too large for this web viewer (${(h.total / 1e6).toFixed(0)} MB; ` +
        `at most ${MAX_BYTES / 1e6} MB): publish a smaller mesh.`);
    }
    return h;
  }

  // ------------------------------------------------------------------ decoding

  /** The mesh after each record, built one record at a time from the base mesh. */
  class Decoder {
    constructor(h, bytes) {
      this.h = h;
      const n = h.nb + h.nr;
      this.nb = h.nb;
      this.pos32 = new Float32Array(3 * n); // what WebGL draws
      this.pos64 = h.f64 ? new Float64Array(3 * n) : null; // the exact positions of a float64 file
      this.F = new Uint32Array(3 * (h.fb + 2 * h.nr));
      this.nf = h.fb;
      this.recV = new Int32Array(h.nr); // each record's v, to undo it
      this.movedAt = new Int32Array(h.nr + 1); // records' moved corners in ``moved``
      this.moved = new Int32Array(Math.max(16, 4 * h.nr));
      this.facesAfter = new Int32Array(h.nr + 1);
      this.facesAfter[0] = h.fb;
      this.done = 0; // records applied
      const dv = new DataView(bytes.buffer, bytes.byteOffset, h.recordsAt);
      for (let i = 0; i < 3 * h.nb; i++) {
        const x = h.f64 ? dv.getFloat64(HEADER + 8 * i, true) : dv.getFloat32(HEADER + 4 * i, true);
        if (!Number.isFinite(x)) throw corrupted("a base vertex has a non-finite coordinate");
        this.pos32[i] = x;
        if (this.pos64) this.pos64[i] = x;
      }
      const deg = new Int32Array(n);
      for (let i = 0; i < 3 * h.fb; i++) {
        const x = dv.getUint32(h.facesAt + 4 * i, true);
        if (x >= h.nb) throw corrupted("a base face refers to a missing vertex");
        this.F[i] = x;
        deg[x]++;
      }
      this.levels = new Uint32Array(h.nl);
      let prev = 0;
      for (let i = 0; i < h.nl; i++) {
        const x = dv.getUint32(h.levelsAt + 4 * i, true);
        if (x <= prev || x > h.nr) throw corrupted("its level table is out of order");
        this.levels[i] = prev = x;
      }
      if (prev !== h.nr) throw corrupted("its level table does not end at the last record");
      // each vertex's corners (flat ids into F), ascending, in a block of a pool: start, count, room
      this.start = new Int32Array(n);
      this.deg = new Int32Array(n);
      this.room = new Int32Array(n);
      let top = 0;
      for (let x = 0; x < h.nb; x++) {
        this.start[x] = top;
        this.room[x] = Math.max(8, deg[x] + 4);
        top += this.room[x];
      }
      this.pool = new Int32Array(2 * top + 64); // (grows as the records add vertices)
      this.top = top;
      for (let c = 0; c < 3 * h.fb; c++) {
        const x = this.F[c];
        this.pool[this.start[x] + this.deg[x]++] = c;
      }
      this.scratch = new Int32Array(64);
      this.nxs = new Int32Array(64); // the moved faces' vertices after and before v
      this.pvs = new Int32Array(64);
    }

    /** A block of ``room`` slots at the pool's end (the pool doubles when full). */
    alloc(room) {
      if (this.top + room > this.pool.length) {
        const bigger = new Int32Array(2 * (this.top + room));
        bigger.set(this.pool.subarray(0, this.top));
        this.pool = bigger;
      }
      const at = this.top;
      this.top += room;
      return at;
    }

    /** Corner ``c`` appended to vertex x's list (it is the highest corner so far). */
    push(x, c) {
      if (this.deg[x] === this.room[x]) {
        const room = 2 * this.room[x] + 4;
        const at = this.alloc(room);
        this.pool.copyWithin(at, this.start[x], this.start[x] + this.deg[x]);
        this.start[x] = at;
        this.room[x] = room;
      }
      this.pool[this.start[x] + this.deg[x]++] = c;
    }

    /** Apply record r, read from the file's bytes at byte ``o`` (``dv`` a DataView of them, ``u32`` and
     *  ``f32`` views of the same buffer: records start at multiples of 4); ``limit``: vertices its level
     *  may split. */
    apply(r, dv, u32, f32, o, limit) {
      const h = this.h;
      const F = this.F;
      const u = h.nb + r;
      let w = o >> 2;
      for (let i = 0; i < 3; i++) {
        const x = this.pos64 ? dv.getFloat64(o + 8 * i, true) : f32[w + i];
        if (!Number.isFinite(x)) throw corrupted(`record ${r} has a non-finite coordinate`);
        this.pos32[3 * u + i] = x;
        if (this.pos64) this.pos64[3 * u + i] = x;
      }
      w += this.pos64 ? 6 : 3;
      const vf = u32[w];
      const lo = u32[w + 1];
      const hi = u32[w + 2];
      const v = vf & 0x3fffffff;
      const flags = vf >>> 30;
      if (v >= limit) throw corrupted(`record ${r} splits a vertex its level has not got yet`);
      const s = this.start[v];
      const d = this.deg[v];
      const pool = this.pool;
      // the moved corners (rank bit set; ranks past 63 read bit 63), the kept ones compacted in place
      let sc = this.scratch;
      if (sc.length < d) sc = this.scratch = new Int32Array(2 * d);
      let nm = 0, nk = 0;
      let cp = -1, cq = -1;
      const named = h.version >= 2 && d <= ENDS_SHIFT;
      const rp = (hi >>> 20) & NO_END;
      const rq = hi >>> 26;
      if (named && rp !== NO_END && rq !== NO_END) {
        if (rp >= d || rq >= d) throw corrupted(`record ${r} names faces its vertex has not`);
        cp = pool[s + rp];
        cq = pool[s + rq];
      }
      for (let i = 0; i < d; i++) {
        const c = pool[s + i];
        const bit = i < 32 ? (lo >>> i) & 1 : (hi >>> Math.min(i - 32, 31)) & 1;
        if (bit) sc[nm++] = c;
        else pool[s + nk++] = c;
      }
      // p and q: the one "next" vertex of the arc that is no face's "previous", and the reverse
      if (this.nxs.length < nm) {
        this.nxs = new Int32Array(2 * nm);
        this.pvs = new Int32Array(2 * nm);
      }
      const NX = this.nxs, PV = this.pvs;
      for (let i = 0; i < nm; i++) {
        const c = sc[i];
        const f = c - (c % 3);
        NX[i] = F[f + NEXT[c % 3]];
        PV[i] = F[f + PREV[c % 3]];
      }
      let p = -1, q = -1;
      for (let i = 0; i < nm; i++) {
        const nx = NX[i], pv = PV[i];
        let nxIsPrev = false, pvIsNext = false;
        for (let j = 0; j < nm; j++) {
          if (PV[j] === nx) nxIsPrev = true;
          if (NX[j] === pv) pvIsNext = true;
        }
        if (!nxIsPrev) {
          if (p >= 0) throw corrupted(`record ${r} moves faces that are not one arc`);
          p = nx;
        }
        if (!pvIsNext) {
          if (q >= 0) throw corrupted(`record ${r} moves faces that are not one arc`);
          q = pv;
        }
      }
      if (p < 0 || q < 0) throw corrupted(`record ${r} moves faces that are not one open arc`);
      if (cp >= 0 && (F[cp - (cp % 3) + ((cp + 1) % 3)] !== p || F[cq - (cq % 3) + ((cq + 2) % 3)] !== q)) {
        throw corrupted(`record ${r} names other end faces than its arc's`);
      }
      // move the corners to u, and log them (to go back to an earlier level)
      let m = this.movedAt[r];
      if (m + nm > this.moved.length) {
        const bigger = new Int32Array(2 * (m + nm));
        bigger.set(this.moved);
        this.moved = bigger;
      }
      const at = this.alloc(nm + 8); // (the pool may grow: this.pool, not the earlier ``pool``)
      this.start[u] = at;
      this.room[u] = nm + 8;
      const grown = this.pool;
      for (let i = 0; i < nm; i++) {
        F[sc[i]] = u;
        grown[at + i] = sc[i];
        this.moved[m++] = sc[i];
      }
      this.movedAt[r + 1] = m;
      this.deg[u] = nm;
      this.deg[v] = nk;
      this.recV[r] = v;
      // the new faces [u, v, p] and/or [u, q, v]
      const single = (flags & FLAG_SINGLE) !== 0;
      if (!single || !(flags & FLAG_SECOND)) {
        const c = 3 * this.nf++;
        F[c] = u; F[c + 1] = v; F[c + 2] = p;
        this.push(u, c); this.push(v, c + 1); this.push(p, c + 2);
      }
      if (!single || (flags & FLAG_SECOND)) {
        const c = 3 * this.nf++;
        F[c] = u; F[c + 1] = q; F[c + 2] = v;
        this.push(u, c); this.push(q, c + 1); this.push(v, c + 2);
      }
      this.facesAfter[r + 1] = this.nf;
      this.done = r + 1;
    }

    /** The faces (3 m,) after the first k records (k <= done): the decoded faces with the later
     *  records' moves undone, the later faces dropped. */
    facesAt(k) {
      const m = this.facesAfter[k];
      if (k === this.done) return this.F.subarray(0, 3 * m);
      const G = this.F.slice(0, 3 * this.facesAfter[this.done]);
      for (let r = this.done - 1; r >= k; r--) {
        const v = this.recV[r];
        for (let i = this.movedAt[r]; i < this.movedAt[r + 1]; i++) G[this.moved[i]] = v;
      }
      return G.subarray(0, 3 * m);
    }

    /** SHA-256 (hex) of the mesh after k records: positions as float64 then faces as int64, little
     *  endian (pmwm.key.mesh_sha256(V, F, "<f8") of `pmwm decode --level k`). */
    hash(k) {
      const n = this.nb + k;
      const sha = new Sha256();
      const P = this.pos64 ? this.pos64.subarray(0, 3 * n) : Float64Array.from(this.pos32.subarray(0, 3 * n));
      sha.update(new Uint8Array(P.buffer, P.byteOffset, P.byteLength));
      const faces = this.facesAt(k);
      const chunk = new Uint32Array(2 * Math.min(faces.length, 1 << 16));
      for (let i = 0; i < faces.length; i += chunk.length / 2) {
        const part = faces.subarray(i, i + chunk.length / 2);
        for (let j = 0; j < part.length; j++) chunk[2 * j] = part[j];
        sha.update(new Uint8Array(chunk.buffer, 0, 8 * part.length));
      }
      return hex(sha.digest());
    }

    /** A binary little-endian PLY of the mesh after k records (float32 or double as in the file). */
    ply(k, comment) {
      const n = this.nb + k;
      const faces = this.facesAt(k);
      const m = faces.length / 3;
      const t = this.pos64 ? "double" : "float";
      const head = new TextEncoder().encode(
        `ply\nformat binary_little_endian 1.0\ncomment ${comment}\nelement vertex ${n}\n` +
        `property ${t} x\nproperty ${t} y\nproperty ${t} z\nelement face ${m}\n` +
        "property list uchar int vertex_indices\nend_header\n");
      const vb = n * 3 * (this.pos64 ? 8 : 4);
      const out = new Uint8Array(head.length + vb + 13 * m);
      out.set(head, 0);
      const P = this.pos64 ? this.pos64.subarray(0, 3 * n) : this.pos32.subarray(0, 3 * n);
      out.set(new Uint8Array(P.buffer, P.byteOffset, vb), head.length);
      const dv = new DataView(out.buffer, head.length + vb);
      for (let f = 0; f < m; f++) {
        dv.setUint8(13 * f, 3);
        dv.setInt32(13 * f + 1, faces[3 * f], true);
        dv.setInt32(13 * f + 5, faces[3 * f + 1], true);
        dv.setInt32(13 * f + 9, faces[3 * f + 2], true);
      }
      return out;
    }
  }

  // ------------------------------------------------------------------ the stream

  /** Reads the file as it arrives: header, base mesh, then level after level (up to ``target``
   *  records), and the checksum at the last byte. Calls ``onLevel(ks)`` with the levels (records)
   *  each chunk completed; throws PmError. */
  class StreamReader {
    constructor(target, onLevel) {
      this.decodeMs = 0; // spent applying records
      this.shaMs = 0; // spent on the checksum
      this.target = target; // records to decode (null: all)
      this.onLevel = onLevel;
      this.head = new Uint8Array(HEADER);
      this.got = 0;
      this.h = null;
      this.bytes = null;
      this.sha = new Sha256();
      this.hashed = 0;
      this.dec = null;
      this.level = 0; // the file's level holding the next record
    }

    push(chunk) {
      let i = 0;
      if (!this.h) {
        const t = Math.min(HEADER - this.got, chunk.length);
        this.head.set(chunk.subarray(0, t), this.got);
        this.got += t;
        i = t;
        if (this.got < HEADER) return;
        this.h = parseHeader(this.head);
        this.room(HEADER);
        this.bytes.set(this.head, 0);
        this.target = this.target === null ? this.h.nr : Math.min(this.target, this.h.nr);
      }
      const rest = chunk.length - i;
      if (this.got + rest > this.h.total) {
        throw corrupted(`it is longer than its header promises (${this.h.total} bytes)`);
      }
      this.room(this.got + rest);
      this.bytes.set(chunk.subarray(i), this.got);
      this.got += rest;
      const upto = Math.min(this.got, this.h.total - DIGEST);
      if (upto > this.hashed) {
        const t0 = performance.now();
        this.sha.update(this.bytes.subarray(this.hashed, upto));
        this.hashed = upto;
        this.shaMs += performance.now() - t0;
      }
      this.advance();
    }

    /** Room for ``n`` bytes of the file: the buffer grows with what arrives (a damaged header that
     *  promises a huge file costs nothing until the bytes come), in multiples of 4 bytes (records
     *  start at multiples of 4: typed views read them). */
    room(n) {
      if (this.bytes && this.bytes.length >= n) return;
      const size = Math.min(this.h.total, Math.max(n, 2 * (this.bytes ? this.bytes.length : 0), 1 << 20));
      const bigger = new Uint8Array(size + ((4 - (size % 4)) % 4));
      if (this.bytes) bigger.set(this.bytes.subarray(0, this.got));
      this.bytes = bigger;
      this.dv = new DataView(bigger.buffer);
      this.u32 = new Uint32Array(bigger.buffer);
      this.f32 = new Float32Array(bigger.buffer);
    }

    advance() {
      const h = this.h;
      if (!this.dec) {
        if (this.got < h.recordsAt) return;
        this.dec = new Decoder(h, this.bytes);
        this.onLevel([0]);
      }
      const dec = this.dec;
      const have = Math.floor(Math.max(0, this.got - h.recordsAt) / h.rsize);
      const upto = Math.min(have, this.target);
      // every record in is applied (a level's records as they arrive, not when the level is whole);
      // the levels completed are reported, and shown from the records (``facesAt``)
      const reached = [];
      const t0 = performance.now();
      while (dec.done < upto) {
        const last = dec.levels[this.level];
        const end = Math.min(last, upto);
        const limit = h.nb + (this.level ? dec.levels[this.level - 1] : 0);
        for (let r = dec.done; r < end; r++) dec.apply(r, this.dv, this.u32, this.f32, h.recordsAt + r * h.rsize, limit);
        if (end === last) {
          this.level++;
          reached.push(end);
        } else if (end === this.target) {
          reached.push(end);
        }
      }
      this.decodeMs += performance.now() - t0;
      if (reached.length) this.onLevel(reached);
    }

    /** The stream ended: check its length and its checksum. */
    finish() {
      const h = this.h;
      if (!h || this.got < h.total) {
        const promised = h ? ` of the ${h.total} its header promises` : "";
        throw new PmError("truncated", `The model file is truncated: ${this.got} bytes arrived${promised}.`);
      }
      const sum = this.sha.digest();
      const stored = this.bytes.subarray(h.total - DIGEST, h.total);
      for (let i = 0; i < DIGEST; i++) {
        if (sum[i] !== stored[i]) throw corrupted("its checksum does not match");
      }
    }
  }

  // ------------------------------------------------------------------ drawing (WebGL 2)

  const VS = `#version 300 es
in vec3 pos;
uniform mat4 mvp;
out vec3 vp;
void main() { vp = pos; gl_Position = mvp * vec4(pos, 1.0); }`;
  const FS = `#version 300 es
precision highp float;
in vec3 vp;
uniform vec3 eye;
out vec4 color;
void main() {
  vec3 n = normalize(cross(dFdx(vp), dFdy(vp)));
  float l = abs(dot(n, normalize(eye - vp)));
  color = vec4(vec3(0.16, 0.17, 0.2) + vec3(0.66, 0.68, 0.72) * l, 1.0);
}`;

  function mat4Mul(a, b) {
    const o = new Float32Array(16);
    for (let i = 0; i < 4; i++) {
      for (let j = 0; j < 4; j++) {
        let s = 0;
        for (let k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k];
        o[i * 4 + j] = s;
      }
    }
    return o;
  }

  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2);
    const o = new Float32Array(16);
    o[0] = f / aspect; o[5] = f; o[10] = (far + near) / (near - far); o[11] = -1;
    o[14] = (2 * far * near) / (near - far);
    return o;
  }

  function lookAt(eye, c, up) {
    const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const z = norm(sub(eye, c));
    const x = norm(cross(up, z));
    const y = cross(z, x);
    return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
      -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
  }

  class Renderer {
    constructor(canvas) {
      this.canvas = canvas;
      const gl = canvas.getContext("webgl2", { antialias: true });
      this.gl = gl;
      this.count = 0;
      this.yaw = 0.6;
      this.pitch = 0.35;
      this.dist = 3;
      this.center = [0, 0, 0];
      this.radius = 1;
      this.pending = false;
      this.drawMs = 0; // spent uploading and drawing
      if (!gl) return;
      const sh = (type, src) => {
        const s = gl.createShader(type);
        gl.shaderSource(s, src);
        gl.compileShader(s);
        if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
        return s;
      };
      const prog = gl.createProgram();
      gl.attachShader(prog, sh(gl.VERTEX_SHADER, VS));
      gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, FS));
      gl.linkProgram(prog);
      this.prog = prog;
      this.uMvp = gl.getUniformLocation(prog, "mvp");
      this.uEye = gl.getUniformLocation(prog, "eye");
      this.vao = gl.createVertexArray();
      gl.bindVertexArray(this.vao);
      this.vbo = gl.createBuffer();
      this.ibo = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, this.vbo);
      const loc = gl.getAttribLocation(prog, "pos");
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.ibo);
      this.orbit();
    }

    /** Frame the first mesh shown: its bounding box's centre and half diagonal. */
    frame(P, n) {
      const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
      for (let i = 0; i < n; i++) {
        for (let j = 0; j < 3; j++) {
          const x = P[3 * i + j];
          if (x < lo[j]) lo[j] = x;
          if (x > hi[j]) hi[j] = x;
        }
      }
      if (!n) return;
      this.center = [0, 1, 2].map((j) => (lo[j] + hi[j]) / 2);
      this.radius = Math.max(1e-12, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
      this.dist = 2.6 * this.radius;
    }

    /** Show a mesh from the next frame on: ``source()`` gives [positions, vertex count, faces] then
     *  (so that levels decoded before the frame cost no upload). */
    set(source) {
      this.source = source;
      this.requestDraw();
    }

    clear() {
      this.source = null;
      this.count = 0;
      this.requestDraw();
    }

    requestDraw() {
      if (this.pending) return;
      this.pending = true;
      requestAnimationFrame(() => {
        const t0 = performance.now();
        this.pending = false;
        if (this.source) this.upload(...this.source());
        this.source = null;
        this.draw();
        this.drawMs += performance.now() - t0;
      });
    }

    upload(P, n, faces) {
      const gl = this.gl;
      this.count = faces.length;
      if (!gl) return;
      gl.bindBuffer(gl.ARRAY_BUFFER, this.vbo);
      gl.bufferData(gl.ARRAY_BUFFER, P.subarray(0, 3 * n), gl.DYNAMIC_DRAW);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.ibo);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, faces, gl.DYNAMIC_DRAW);
    }

    draw() {
      const gl = this.gl;
      if (!gl) return;
      const c = this.canvas;
      const dpr = window.devicePixelRatio || 1;
      const w = Math.max(1, Math.round(c.clientWidth * dpr)), hgt = Math.max(1, Math.round(c.clientHeight * dpr));
      if (c.width !== w || c.height !== hgt) { c.width = w; c.height = hgt; }
      gl.viewport(0, 0, w, hgt);
      gl.clearColor(0.93, 0.94, 0.95, 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      if (!this.count) return;
      const cp = Math.cos(this.pitch);
      const eye = [this.center[0] + this.dist * cp * Math.sin(this.yaw), this.center[1] + this.dist * Math.sin(this.pitch),
        this.center[2] + this.dist * cp * Math.cos(this.yaw)];
      const near = Math.max(this.dist - 2 * this.radius, this.dist * 0.01), far = this.dist + 2 * this.radius;
      const mvp = mat4Mul(perspective(0.8, w / hgt, near, far), lookAt(eye, this.center, [0, 1, 0]));
      gl.enable(gl.DEPTH_TEST);
      gl.useProgram(this.prog);
      gl.uniformMatrix4fv(this.uMvp, false, mvp);
      gl.uniform3fv(this.uEye, eye);
      gl.bindVertexArray(this.vao);
      gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_INT, 0);
    }

    /** Drag to turn, wheel or pinch to zoom, double-click to reset. */
    orbit() {
      const c = this.canvas;
      const pointers = new Map();
      let spread = 0;
      c.addEventListener("pointerdown", (e) => { c.setPointerCapture(e.pointerId); pointers.set(e.pointerId, e); });
      const up = (e) => { pointers.delete(e.pointerId); spread = 0; };
      c.addEventListener("pointerup", up);
      c.addEventListener("pointercancel", up);
      c.addEventListener("pointermove", (e) => {
        const last = pointers.get(e.pointerId);
        if (!last) return;
        pointers.set(e.pointerId, e);
        if (pointers.size === 1) {
          this.yaw -= (e.clientX - last.clientX) * 0.008;
          this.pitch = Math.max(-1.55, Math.min(1.55, this.pitch + (e.clientY - last.clientY) * 0.008));
        } else if (pointers.size === 2) {
          const [a, b] = [...pointers.values()];
          const now = Math.hypot(a.clientX - b.clientX, a.clientY - b.clientY);
          if (spread) this.zoom(spread / now);
          spread = now;
        }
        this.requestDraw();
      });
      c.addEventListener("wheel", (e) => { e.preventDefault(); this.zoom(Math.exp(e.deltaY * 0.001)); this.requestDraw(); },
        { passive: false });
      c.addEventListener("dblclick", () => { this.yaw = 0.6; this.pitch = 0.35; this.dist = 2.6 * this.radius; this.requestDraw(); });
      window.addEventListener("resize", () => this.requestDraw());
    }

    zoom(factor) {
      this.dist = Math.max(0.05 * this.radius, Math.min(50 * this.radius, this.dist * factor));
    }
  }

  // ------------------------------------------------------------------ the page

  const $ = (id) => document.getElementById(id);
  const fmt = (x) => x.toLocaleString("en-US");

  class Viewer {
    constructor(root) {
      this.url = root.dataset.model || "model.pmwm";
      this.status = $("pmwm-status");
      this.counter = $("pmwm-counter");
      this.message = $("pmwm-message");
      this.slider = $("pmwm-slider");
      this.download = $("pmwm-download");
      this.hashButton = $("pmwm-hash-button");
      this.hashOut = $("pmwm-hash");
      this.renderer = new Renderer($("pmwm-canvas"));
      this.reader = null;
      this.stops = []; // the levels (records) the slider can show
      this.shown = -1;
      this.follow = true; // show each new level as it arrives (until the slider is moved back)
      this.done = false; // the whole file is in and checked
      this.timing = {};
      this.slider.addEventListener("input", () => {
        const i = Number(this.slider.value);
        this.follow = i === this.stops.length - 1;
        this.show(this.stops[i]);
      });
      this.download.addEventListener("click", () => this.save());
      this.hashButton.addEventListener("click", () => this.showHash());
      this.note = this.renderer.gl ? "" : "This browser cannot draw 3D here (WebGL 2 is off); the counter, hash " +
        "and download still work.";
      this.say(this.note);
    }

    say(text, isError) {
      this.message.textContent = text;
      this.message.hidden = !text;
      this.message.classList.toggle("error", !!isError);
    }

    mark(attrs) {
      for (const [k, v] of Object.entries(attrs)) this.status.setAttribute(`data-${k}`, String(v));
    }

    async run() {
      const params = new URLSearchParams(location.search);
      let target = null;
      if (params.has("level")) {
        const raw = params.get("level");
        if (!/^\d+$/.test(raw)) throw new PmError("usage", `?level=${raw}: give a number of records, 0 or more.`);
        target = Number(raw);
      }
      if (location.protocol === "file:") {
        throw new PmError("network", "Open this page through a web server (for example: python -m http.server " +
          "in its folder), not as a file: browsers do not stream files opened from disk.");
      }
      if (!LITTLE) throw new PmError("format", "This viewer needs a little-endian machine.");
      this.mark({ state: "loading", done: "false" });
      this.timing.start = performance.now();
      let resp;
      try {
        resp = await fetch(this.url);
      } catch (e) {
        throw new PmError("network", `Could not load ${this.url}: ${e.message}.`);
      }
      if (!resp.ok) throw new PmError("network", `Could not load ${this.url}: HTTP ${resp.status} ${resp.statusText}.`);
      const reader = new StreamReader(target, (k) => this.arrived(k));
      this.reader = reader;
      const body = resp.body.getReader();
      for (;;) {
        let part;
        try {
          part = await body.read();
        } catch (e) {
          if (this.done) return; // the whole file was in and checked
          reader.finish(); // truncated: names what arrived (throws)
          throw new PmError("network", `The download broke off: ${e.message}.`);
        }
        if (part.done) break;
        const t = performance.now();
        reader.push(part.value); // (throws on bytes past the file's end: it was padded)
        if (!this.done && reader.h && reader.got === reader.h.total) {
          // every byte the header promises is in: done now (the server may close the stream later)
          this.timing.lastByte = t;
          reader.finish();
          this.complete();
        }
      }
      if (!this.done) reader.finish(); // throws: the file ended early
    }

    /** The whole file is in and checked. */
    complete() {
      const reader = this.reader;
      this.done = true;
      this.timing.done = performance.now();
      Object.assign(this.timing, { records: reader.decodeMs, checksum: reader.shaMs, draw: this.renderer.drawMs });
      this.mark({ state: "done", done: "true", "decode-ms": (this.timing.done - this.timing.lastByte).toFixed(1),
        "records-ms": reader.decodeMs.toFixed(1) });
      if (reader.target < reader.h.nr) {
        this.say(`Stopped at level ${fmt(reader.target)} of ${fmt(reader.h.nr)} as the address asks (?level=); ` +
          "the whole file was checked.");
      } else {
        this.say(this.note);
      }
      this.counter.title = `${fmt(reader.dec.done)} of ${fmt(reader.h.nr)} records; file checked (SHA-256)`;
    }

    /** New levels are decoded: slider stops, and the last one shown when following. */
    arrived(ks) {
      const h = this.reader.h;
      const k = ks[ks.length - 1];
      if (k === 0) {
        this.renderer.frame(this.reader.dec.pos32, h.nb);
        this.mark({ levels: h.nr, steps: h.nl });
      }
      this.stops.push(...ks);
      this.slider.max = String(this.stops.length - 1);
      this.slider.disabled = this.stops.length < 2;
      this.download.disabled = false;
      this.hashButton.disabled = false;
      this.mark({ received: k });
      if (this.follow) {
        this.slider.value = this.slider.max;
        this.show(k);
      }
    }

    show(k) {
      const dec = this.reader.dec;
      const m = dec.facesAfter[k];
      this.shown = k;
      this.renderer.set(() => [dec.pos32, dec.nb + k, dec.facesAt(k)]);
      const step = k === 0 ? 0 : dec.levels.indexOf(k) + 1; // the file's levels (0: not at one's end)
      this.counter.textContent = `${fmt(dec.nb + k)} vertices · ${fmt(m)} faces · ` +
        `level ${fmt(k)} of ${fmt(this.reader.h.nr)}` + (step || !k ? ` (step ${step} of ${this.reader.h.nl})` : "");
      this.mark({ level: k, vertices: dec.nb + k, faces: m });
      this.hashOut.textContent = "";
      this.status.removeAttribute("data-hash");
    }

    showHash() {
      if (this.shown < 0) return;
      const hx = this.reader.dec.hash(this.shown);
      this.hashOut.textContent = `SHA-256 of level ${this.shown}: ${hx}`;
      this.mark({ hash: hx });
    }

    save() {
      if (this.shown < 0) return;
      const name = (this.url.split("/").pop() || "model").replace(/\.pmwm$/i, "");
      const data = this.reader.dec.ply(this.shown, `pmwm viewer: ${name}.pmwm level ${this.shown}`);
      const a = document.createElement("a");
      a.href = URL.createObjectURL(new Blob([data], { type: "application/octet-stream" }));
      a.download = `${name}-level-${this.shown}.ply`;
      document.body.appendChild(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(a.href), 60000);
    }

    fail(e) {
      const kind = e instanceof PmError ? e.kind : "internal";
      const text = e instanceof PmError ? e.message : `The viewer stopped on an error: ${e.message}.`;
      const attrs = { state: "error", done: "false", error: kind };
      if (kind === "truncated" && this.reader && this.reader.dec && this.shown >= 0) {
        // what arrived is shown at its last complete level, said to be unchecked
        this.say(`${text} Showing level ${fmt(this.shown)}, the last complete one; it could not be checked ` +
          "(the checksum is at the end of the file).", true);
      } else {
        // nothing that may be damaged stays on screen or downloadable
        this.renderer.clear();
        this.stops = [];
        this.slider.disabled = this.download.disabled = this.hashButton.disabled = true;
        this.counter.textContent = "no mesh";
        Object.assign(attrs, { level: -1, vertices: 0, faces: 0 });
        this.shown = -1;
        this.hashOut.textContent = "";
        this.say(text, true);
      }
      this.mark(attrs);
    }
  }

  const root = $("pmwm-viewer");
  const viewer = new Viewer(root);
  window.pmwmViewer = viewer; // for scripts: viewer.reader.dec, viewer.timing
  viewer.run().catch((e) => viewer.fail(e));
})();
