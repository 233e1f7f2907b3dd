// fourd's web player, the browser side (docs/web.md): draws what the runtime (WebAssembly,
// fourd_web.js) plays and forwards input to it. All motion logic (blending, the motion graph,
// transitions, the controller, the camera) runs in the module; this file only uploads and draws
// (WebGL2: the blended positions and normals as a float texture the vertex shader reads by
// vertex index, the key textures as a texture array blended in the fragment shader with the
// runtime's weights, as fourd-view does) and shows the HUD.
//
// API for scripts and tests: window.fourd (after window.fourd.ready resolves):
//   load(url) / loadBytes(Uint8Array, name)    load an asset; resolves to its info
//   runScript(text, {recordEvery, showFrame})  play a control script as fourd-play does:
//                                              {summary, frames: [...], positions: Float32Array}
//   render({camera, unlit, width, height})     draw the shown frame once, returns a PNG data URL
//   measureFps(seconds, width, height)         live play at that size: {fps, frame_ms, ...}
//   benchmark(steps, dt, evictMb)              the runtime step benchmark (web/step_benchmark.h;
//                                              evictMb: cold caches before every step)
//   state()                                    what the HUD shows
'use strict';
(() => {
  const canvas = document.getElementById('view');
  const hud = document.getElementById('hud');
  const message = document.getElementById('message');
  const $ = (id) => document.getElementById(id);
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: true, premultipliedAlpha: false,
                                           preserveDrawingBuffer: false });
  let M = null;        // the module
  let info = null;     // the asset's
  let live = true;     // the animation loop plays (false while a script's frame is shown)
  let last = 0;
  const keys = new Set();
  const frameMs = [];
  const stepHistory = [];
  let stepMs = 0;

  const mean = (a) => a.reduce((x, y) => x + y, 0) / Math.max(a.length, 1);
  function fail(text) {
    message.textContent = text;
    console.error(text);
  }

  // ---- GL resources
  function compile(kind, source) {
    const s = gl.createShader(kind);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  function program(vs, fs) {
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl.VERTEX_SHADER, vs));
    gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; ++i) {
      const name = gl.getActiveUniform(p, i).name.replace(/\[0\]$/, '');
      u[name] = gl.getUniformLocation(p, name);
    }
    return { p, u };
  }
  const kShapeWidth = 1024;  // texels per row of the shape texture
  const characterProgram = program(`#version 300 es
    precision highp float; precision highp int; precision highp sampler2D;
    layout(location = 0) in int a_source;
    layout(location = 1) in vec2 a_uv;
    uniform sampler2D u_shape;  // positions x | y | z planes, then normals x | y | z
    uniform int u_stride;
    uniform vec3 u_root;        // x, y [m], heading [rad]
    uniform mat4 u_view_projection;
    out vec3 v_world; out vec3 v_normal; out vec2 v_uv;
    float at(int i) { return texelFetch(u_shape, ivec2(i & ${kShapeWidth - 1}, i >> ${Math.log2(kShapeWidth)}), 0).r; }
    vec3 fetch(int base) {
      return vec3(at(base + a_source), at(base + u_stride + a_source), at(base + 2 * u_stride + a_source));
    }
    void main() {
      float c = cos(u_root.z), s = sin(u_root.z);
      mat3 rotation = mat3(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
      v_world = rotation * fetch(0) + vec3(u_root.xy, 0.0);
      v_normal = rotation * fetch(3 * u_stride);
      v_uv = a_uv;
      gl_Position = u_view_projection * vec4(v_world, 1.0);
    }`, `#version 300 es
    precision highp float; precision highp int; precision highp sampler2DArray;
    in vec3 v_world; in vec3 v_normal; in vec2 v_uv;
    uniform vec3 u_eye;
    uniform sampler2DArray u_keys;
    uniform int u_count;
    uniform int u_unlit;
    uniform int u_layers[12];
    uniform float u_weights[12];
    out vec4 o_color;
    void main() {
      vec3 n = normalize(v_normal);
      if (dot(n, u_eye - v_world) < 0.0) n = -n;  // the inside of an open surface
      const vec3 light = normalize(vec3(0.45, 0.3, 0.84));
      float diffuse = max(dot(n, light), 0.0);
      float sky = 0.5 + 0.5 * n.z;
      vec3 color;
      if (u_count > 0) {
        // The captured appearance blended with the runtime's weights (it holds the studio's
        // lighting: shading only adds relief, as in fourd-view).
        vec3 albedo = vec3(0.0);
        for (int k = 0; k < 12; ++k) {
          if (k >= u_count) break;
          albedo += u_weights[k] * texture(u_keys, vec3(v_uv.x, 1.0 - v_uv.y, float(u_layers[k]))).rgb;
        }
        color = u_unlit == 1 ? albedo : albedo * (0.7 + 0.15 * sky + 0.25 * diffuse);
      } else {
        color = vec3(0.78, 0.62, 0.5) * (0.22 + 0.28 * sky + 0.7 * diffuse);
      }
      o_color = vec4(color, 1.0);
    }`);
  // The ground: the frame cleared to its colour, the sky drawn over it above the horizon, and
  // metre lines 25 m around the character as line primitives (every 5th brighter, the world axes
  // red (x) and green (y): fourd-view's grid). Under software WebGL every pixel shaded costs:
  // a grid computed per pixel of the ground took as long as the character, and even a flat
  // ground square twice as long as the sky above the horizon.
  const kGround = 25;  // half size [m]
  const groundProgram = program(`#version 300 es
    precision highp float;
    layout(location = 0) in vec3 a_point;  // z: 0 the sky (x, y in normalised device
                                          // coordinates), 1 a line of constant x, 2 of constant
                                          // y (x, y [m] from the centre)
    uniform mat4 u_view_projection;
    uniform vec2 u_centre;                 // whole metres
    out vec3 v_color;
    void main() {
      if (a_point.z < 0.5) {
        v_color = vec3(0.62, 0.68, 0.74);
        gl_Position = vec4(a_point.xy, 0.0, 1.0);
        return;
      }
      vec2 world = u_centre + a_point.xy;
      float at = a_point.z < 1.5 ? world.x : world.y;  // the line's own coordinate
      v_color = abs(at) < 0.5 ? (a_point.z < 1.5 ? vec3(0.3, 0.75, 0.3) : vec3(0.8, 0.3, 0.3))
              : abs(mod(at + 0.5, 5.0) - 0.5) < 0.25 ? vec3(0.66) : vec3(0.56);
      gl_Position = u_view_projection * vec4(world, 0.0, 1.0);
    }`, `#version 300 es
    precision mediump float;
    in vec3 v_color;
    out vec4 o_color;
    void main() { o_color = vec4(v_color, 1.0); }`);
  // The sky's polygon (6 places), then the lines' end points, clipped to the view each frame
  // (groundLines): SwiftShader drops a line whose end points lie far outside the view rather
  // than clipping it, which lost every line near the camera.
  const groundVao = gl.createVertexArray();
  const groundBuffer = gl.createBuffer();
  const groundLineEnds = [];
  for (let i = -kGround; i <= kGround; ++i) {
    groundLineEnds.push([i, -kGround, 1, i, kGround, 1], [-kGround, i, 2, kGround, i, 2]);
  }
  const groundPoints = new Float32Array(3 * (6 + 2 * groundLineEnds.length));
  gl.bindVertexArray(groundVao);
  gl.bindBuffer(gl.ARRAY_BUFFER, groundBuffer);
  gl.bufferData(gl.ARRAY_BUFFER, groundPoints.byteLength, gl.DYNAMIC_DRAW);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
  gl.bindVertexArray(null);

  // The inverse of a 4x4 matrix (column-major; Gauss-Jordan with partial pivoting).
  function invert(m) {
    const a = Array.from({ length: 4 }, (_, r) => [0, 1, 2, 3].map((c) => m[4 * c + r])
                                                .concat([0, 1, 2, 3].map((c) => (c === r ? 1 : 0))));
    for (let c = 0; c < 4; ++c) {
      let pivot = c;
      for (let r = c + 1; r < 4; ++r) if (Math.abs(a[r][c]) > Math.abs(a[pivot][c])) pivot = r;
      [a[c], a[pivot]] = [a[pivot], a[c]];
      const d = a[c][c];
      for (let k = 0; k < 8; ++k) a[c][k] /= d;
      for (let r = 0; r < 4; ++r) {
        if (r === c) continue;
        const f = a[r][c];
        for (let k = 0; k < 8; ++k) a[r][k] -= f * a[c][k];
      }
    }
    const inv = new Float32Array(16);
    for (let r = 0; r < 4; ++r) for (let c = 0; c < 4; ++c) inv[4 * c + r] = a[r][4 + c];
    return inv;
  }

  // Writes the sky's polygon (a triangle fan; returns its number of points): the part of the
  // view whose rays rise above the horizontal through the eye. The far-plane point of normalised
  // device coordinates (x, y) is inv(vp) (x, y, 1, 1), affine in x and y, and so is its height
  // above the eye: the sky is the screen square cut by one straight line.
  function skyPolygon(vp, eye) {
    const inv = invert(vp);
    const rise = (x, y) => {
      const z = inv[2] * x + inv[6] * y + inv[10] + inv[14];
      const w = inv[3] * x + inv[7] * y + inv[11] + inv[15];
      return (z - eye[2] * w) * Math.sign(w);
    };
    const corners = [[-1, -1], [1, -1], [1, 1], [-1, 1]];
    let n = 0;
    corners.forEach(([x, y], k) => {
      const [x1, y1] = corners[(k + 1) % 4];
      const r0 = rise(x, y), r1 = rise(x1, y1);
      if (r0 >= 0) groundPoints.set([x, y, 0], 3 * n++);
      if ((r0 >= 0) !== (r1 >= 0)) {
        const t = r0 / (r0 - r1);
        groundPoints.set([x + t * (x1 - x), y + t * (y1 - y), 0], 3 * n++);
      }
    });
    return n;
  }

  // Writes the parts of the lines inside the view of `vp` (column-major) around `centre` after
  // the sky's places in the ground buffer; returns the number of line end points.
  function groundLines(vp, centre) {
    const clip = (x, y) => {  // clip coordinates of a point of the ground
      const X = centre[0] + x, Y = centre[1] + y;
      return [0, 1, 2, 3].map((r) => vp[r] * X + vp[4 + r] * Y + vp[12 + r]);
    };
    let n = 6;
    for (const [x0, y0, kind, x1, y1] of groundLineEnds) {
      const a = clip(x0, y0), b = clip(x1, y1);
      // The part of a..b inside -w <= x, y, z <= w (Liang-Barsky on the six planes).
      let t0 = 0, t1 = 1;
      for (let axis = 0; axis < 3 && t0 <= t1; ++axis) {
        for (const sign of [1, -1]) {
          const da = a[3] + sign * a[axis], db = b[3] + sign * b[axis];  // >= 0 inside
          if (da < 0 && db < 0) { t0 = 1; t1 = 0; break; }
          if (da < 0) t0 = Math.max(t0, da / (da - db));
          else if (db < 0) t1 = Math.min(t1, da / (da - db));
        }
      }
      if (t0 >= t1) continue;
      groundPoints.set([x0 + t0 * (x1 - x0), y0 + t0 * (y1 - y0), kind,
                        x0 + t1 * (x1 - x0), y0 + t1 * (y1 - y0), kind], 3 * n);
      n += 2;
    }
    return n - 6;
  }

  const character = { vao: null, count: 0, stride: 0, shape: null, staging: null, rows: 0,
                      keys: null, layers: 0, closed: false };

  // Topology, per-corner UVs (vertices on chart seams duplicated, as fourd-view's renderer does)
  // and the shape texture.
  function setMesh(triangles, uvs, vertices, stride) {
    const textured = uvs.length === 2 * triangles.length;
    const sources = [], coords = [], indices = new Uint32Array(triangles.length);
    const ids = new Map();
    for (let c = 0; c < triangles.length; ++c) {
      const v = triangles[c];
      const u = textured ? uvs[2 * c] : 0, w = textured ? uvs[2 * c + 1] : 0;
      const key = textured ? `${v} ${u} ${w}` : v;
      let id = ids.get(key);
      if (id === undefined) {
        id = sources.length;
        ids.set(key, id);
        sources.push(v);
        coords.push(u, w);
      }
      indices[c] = id;
    }
    if (character.vao) gl.deleteVertexArray(character.vao);
    character.vao = gl.createVertexArray();
    gl.bindVertexArray(character.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, new Int32Array(sources), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribIPointer(0, 1, gl.INT, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(coords), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 2, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    character.count = indices.length;
    character.stride = stride;
    character.rows = Math.ceil(6 * stride / kShapeWidth);
    character.staging = new Float32Array(kShapeWidth * character.rows);
    if (character.shape) gl.deleteTexture(character.shape);
    character.shape = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, character.shape);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R32F, kShapeWidth, character.rows);
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
    gl.bindTexture(gl.TEXTURE_2D, null);
    character.closed = closedOutward(triangles, M.positions(), stride);
    return sources.length;
  }

  // Whether the mesh is closed and its triangles face outwards: every edge is shared by exactly
  // two triangles that run along it in opposite directions, and the enclosed volume (of the
  // shown frame) is positive. Then no back face can be seen from outside, and back faces are
  // culled: they are most of the character's hidden pixels, and under software WebGL each of
  // them costs its texture samples. A captured character's template is closed; an open surface
  // is drawn from both sides.
  function closedOutward(triangles, positions, stride) {
    const edges = new Set();
    const key = (a, b) => a * 4294967296 + b;
    for (let t = 0; t < triangles.length; t += 3) {
      for (let k = 0; k < 3; ++k) {
        const e = key(triangles[t + k], triangles[t + (k + 1) % 3]);
        if (edges.has(e)) return false;  // two triangles run along it the same way
        edges.add(e);
      }
    }
    for (let t = 0; t < triangles.length; t += 3) {
      for (let k = 0; k < 3; ++k) {
        if (!edges.has(key(triangles[t + (k + 1) % 3], triangles[t + k]))) return false;  // a border
      }
    }
    let volume = 0;  // six times the signed volume
    const p = (v) => [positions[v], positions[stride + v], positions[2 * stride + v]];
    for (let t = 0; t < triangles.length; t += 3) {
      const [a, b, c] = [p(triangles[t]), p(triangles[t + 1]), p(triangles[t + 2])];
      volume += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return volume > 0;
  }

  // The key textures: the asset's JPEG files, decoded by the browser, one layer each.
  async function uploadKeys(count, width, height) {
    if (character.keys) gl.deleteTexture(character.keys);
    character.keys = null;
    character.layers = 0;
    if (count === 0) return;
    const bitmaps = await Promise.all(Array.from({ length: count }, (_, k) =>
      createImageBitmap(new Blob([M.textureFile(k).slice()], { type: 'image/jpeg' }),
                        { colorSpaceConversion: 'none', premultiplyAlpha: 'none' })));
    character.keys = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, character.keys);
    const levels = 1 + Math.floor(Math.log2(Math.max(width, height)));
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, levels, gl.RGB8, width, height, count);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    bitmaps.forEach((b, k) => {
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, k, width, height, 1, gl.RGB, gl.UNSIGNED_BYTE, b);
      b.close();
    });
    gl.generateMipmap(gl.TEXTURE_2D_ARRAY);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR_MIPMAP_LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, null);
    character.layers = count;
  }

  // The shown frame's shape into the shape texture.
  function uploadShape() {
    const s = character.staging;
    const positions = M.positions(), normals = M.normals();
    s.set(positions, 0);
    s.set(normals, 3 * character.stride);
    gl.bindTexture(gl.TEXTURE_2D, character.shape);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, kShapeWidth, character.rows, gl.RED, gl.FLOAT, s);
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  function drawCharacter(viewProjection, eye, unlit) {
    const { p, u } = characterProgram;
    gl.useProgram(p);
    gl.uniformMatrix4fv(u.u_view_projection, false, viewProjection);
    const r = M.root();
    gl.uniform3f(u.u_root, r[0], r[1], r[2]);
    gl.uniform1i(u.u_stride, character.stride);
    gl.uniform3fv(u.u_eye, eye);
    gl.uniform1i(u.u_unlit, unlit ? 1 : 0);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, character.shape);
    gl.uniform1i(u.u_shape, 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, character.keys);
    gl.uniform1i(u.u_keys, 1);
    const layers = M.textureLayers(), weights = M.textureWeights();
    const count = character.layers > 0 ? Math.min(layers.length, 12) : 0;
    gl.uniform1i(u.u_count, count);
    if (count > 0) {
      gl.uniform1iv(u.u_layers, Int32Array.from(layers));
      gl.uniform1fv(u.u_weights, Float32Array.from(weights));
    }
    if (character.closed) gl.enable(gl.CULL_FACE);  // counter-clockwise in front, back culled
    gl.bindVertexArray(character.vao);
    gl.drawElements(gl.TRIANGLES, character.count, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
    gl.disable(gl.CULL_FACE);
  }

  function drawScene(width, height) {
    M.setViewport(width, height);
    const vp = Float32Array.from(M.viewProjection());
    const eye = Float32Array.from(M.eye());
    gl.viewport(0, 0, width, height);
    gl.clearColor(0.47, 0.5, 0.46, 1);  // the ground's colour
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    // Sky and lines first, without depth: they hide nothing the character draws over them.
    gl.disable(gl.DEPTH_TEST);
    const r = M.root();
    gl.useProgram(groundProgram.p);
    gl.uniformMatrix4fv(groundProgram.u.u_view_projection, false, vp);
    const centre = [Math.round(r[0]), Math.round(r[1])];
    gl.uniform2f(groundProgram.u.u_centre, centre[0], centre[1]);
    const sky = skyPolygon(vp, eye);
    const lines = groundLines(vp, centre);
    gl.bindBuffer(gl.ARRAY_BUFFER, groundBuffer);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, groundPoints, 0, 3 * (6 + lines));
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    gl.bindVertexArray(groundVao);
    if (sky >= 3) gl.drawArrays(gl.TRIANGLE_FAN, 0, sky);
    gl.drawArrays(gl.LINES, 6, lines);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    drawCharacter(vp, eye, false);
  }

  function resize(width, height) {
    if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width;
      canvas.height = height;
    }
  }

  // ---- the loop
  function keyBits() {
    const has = (...names) => names.some((n) => keys.has(n));
    return (has('KeyW', 'ArrowUp') ? 1 : 0) | (has('KeyS', 'ArrowDown') ? 2 : 0) |
           (has('KeyA', 'ArrowLeft') ? 4 : 0) | (has('KeyD', 'ArrowRight') ? 8 : 0);
  }

  let fixedSize = null;  // [width, height] while measuring
  let measuring = false;
  function loop(now) {
    requestAnimationFrame(loop);
    if (!measuring) tick(now);
  }
  function tick(now) {
    if (!info || !live) { last = now; return; }
    const dt = last ? (now - last) / 1000 : 0;
    last = now;
    stepMs = M.frame(dt, keyBits());
    uploadShape();
    const [w, h] = fixedSize || [Math.round(canvas.clientWidth * devicePixelRatio),
                                 Math.round(canvas.clientHeight * devicePixelRatio)];
    resize(w, h);
    drawScene(w, h);
    if (dt > 0) frameMs.push(1000 * dt);
    if (frameMs.length > 120) frameMs.shift();
    stepHistory.push(stepMs);
    if (stepHistory.length > 120) stepHistory.shift();
    if (!fixedSize) updateHud();
  }

  let hudTime = 0;
  function updateHud(force) {
    const now = performance.now();
    if (!force && now - hudTime < 100) return;
    hudTime = now;
    const s = JSON.parse(M.state());
    const ms = mean(frameMs);
    hud.textContent =
      `${info.name}\n` +
      `motion   ${s.motion} (${s.phase})${s.fading ? ', cross-fade' : ''}\n` +
      `${s.parameter.padEnd(8)} ${s.p.toFixed(2)} -> ${s.p_target.toFixed(2)} ${s.unit}\n` +
      `time t   ${s.t.toFixed(3)}   motion time ${s.time.toFixed(2)} s\n` +
      `root     (${s.root[0].toFixed(2)}, ${s.root[1].toFixed(2)}) m, heading ${s.root[2].toFixed(0)} deg\n` +
      `frame    ${ms.toFixed(2)} ms   ${ms > 0 ? (1000 / ms).toFixed(0) : 0} FPS\n` +
      `runtime  ${(1000 * mean(stepHistory)).toFixed(0)} us per step (WebAssembly)\n` +
      (s.request ? `request  ${s.request}` : '');
    $('speed_value').textContent = s.speed.toFixed(2);
  }

  // ---- loading
  // A web package (fourd-export --web) is gzip: the browser's own DecompressionStream inflates
  // it, so the module needs no zlib; a plain asset passes as it is.
  async function inflate(bytes) {
    if (bytes.length < 2 || bytes[0] !== 0x1f || bytes[1] !== 0x8b) return bytes;
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }

  async function loadBytes(bytes, name) {
    const started = performance.now();
    try {
      bytes = await inflate(bytes);
    } catch (e) {
      throw new Error(`${name}: not a readable gzip file (${e.message})`);
    }
    const inflateMs = performance.now() - started;
    M.FS.writeFile('/asset.fourd', bytes);
    const error = M.load('/asset.fourd');
    M.FS.unlink('/asset.fourd');
    if (error) throw new Error(`${name}: ${error}`);
    info = JSON.parse(M.info());
    info.inflate_ms = inflateMs;
    info.load_ms = performance.now() - started;
    const vertices = setMesh(M.triangles().slice(), M.cornerUvs().slice(), info.vertices, info.plane_stride);
    await uploadKeys(info.textures.count, info.textures.width, info.textures.height);
    const loco = info.spaces.find((s) => s.name === 'locomotion');
    if (loco) Object.assign($('speed'), { min: loco.min, max: loco.max, value: info.controls.speed });
    const jump = info.spaces.find((s) => s.name === 'jump_length');
    if (jump) Object.assign($('jump_length'), { min: jump.min, max: jump.max, value: info.controls.jump_length });
    $('jump_value').textContent = info.controls.jump_length.toFixed(2);
    message.textContent = '';
    live = true;
    last = 0;
    console.log(`fourd web: ${name}: ${info.vertices} vertices (${vertices} drawn), ` +
                `${info.triangles} triangles, ${info.spaces.length} motion spaces, ` +
                `${info.textures.count} key textures of ${info.textures.width}x${info.textures.height}` +
                `${character.closed ? ", closed: back faces culled" : ""}`);
    return info;
  }
  async function load(url) {
    const response = await fetch(url);
    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
    return loadBytes(new Uint8Array(await response.arrayBuffer()), url);
  }

  // ---- input
  canvas.addEventListener('keydown', (e) => {
    if (!info) return;
    keys.add(e.code);
    if (e.repeat) return;
    if (e.code === 'Space') M.jump();
    else if (e.code === 'KeyH') M.jumpHeight();
    else if (e.code === 'KeyR') M.reach();
    else if (e.code === 'KeyC') M.toggleCamera();
    else if (e.code === 'KeyP') togglePause();
    else return;
    e.preventDefault();
  });
  canvas.addEventListener('keyup', (e) => keys.delete(e.code));
  canvas.addEventListener('blur', () => keys.clear());
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, moved: false }; canvas.focus(); });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag || !info) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (!drag.moved && Math.hypot(dx, dy) < 3) return;
    drag.moved = true;
    M.cameraDrag(dx, dy);
    drag.x = e.clientX;
    drag.y = e.clientY;
  });
  canvas.addEventListener('pointerup', (e) => {
    if (drag && !drag.moved && info) {
      if (!live) { M.showLive(); live = true; }
      const rect = canvas.getBoundingClientRect();
      M.click((e.clientX - rect.left) * canvas.width / rect.width,
              (e.clientY - rect.top) * canvas.height / rect.height, Number($('click_mode').value));
    }
    drag = null;
  });
  canvas.addEventListener('wheel', (e) => { if (info) { M.cameraZoom(-Math.sign(e.deltaY)); e.preventDefault(); } },
                          { passive: false });
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  let paused = false;
  function togglePause() { paused = !paused; M.setPaused(paused); }
  const button = (id, f) => $(id).addEventListener('click', () => { if (info) { f(); canvas.focus(); } });
  button('jump', () => M.jump());
  button('jump_height', () => M.jumpHeight());
  button('reach', () => M.reach());
  button('camera', () => M.toggleCamera());
  button('pause', togglePause);
  $('speed').addEventListener('input', (e) => info && M.setSpeed(Number(e.target.value)));
  $('jump_length').addEventListener('input', (e) => {
    if (!info) return;
    M.setJumpLength(Number(e.target.value));
    $('jump_value').textContent = Number(e.target.value).toFixed(2);
  });
  $('file').addEventListener('change', async (e) => {
    const file = e.target.files[0];
    if (!file) return;
    try { await loadBytes(new Uint8Array(await file.arrayBuffer()), file.name); } catch (err) { fail(err.message); }
  });

  // ---- the API
  // A camera given in glTF axes (client_check camera: OpenGL projection and the camera's world
  // matrix, column-major): view-projection of our axes (x forward, y left, z up).
  function cameraViewProjection(c) {
    const w = c.matrix_world;
    // Inverse of the rigid world matrix: R^T, -R^T t.
    const inv = new Float32Array(16);
    for (let i = 0; i < 3; ++i) {
      for (let j = 0; j < 3; ++j) inv[4 * j + i] = w[4 * i + j];
      inv[12 + i] = -(w[4 * i] * w[12] + w[4 * i + 1] * w[13] + w[4 * i + 2] * w[14]);
    }
    inv[15] = 1;
    // glTF = (our y, our z, our x).
    const toGltf = [0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1];
    const mul = (a, b) => {
      const o = new Float32Array(16);
      for (let col = 0; col < 4; ++col) {
        for (let row = 0; row < 4; ++row) {
          let s = 0;
          for (let k = 0; k < 4; ++k) s += a[4 * k + row] * b[4 * col + k];
          o[4 * col + row] = s;
        }
      }
      return o;
    };
    const view = mul(inv, toGltf);
    const eye = [w[12], w[13], w[14]];  // glTF -> ours
    return { vp: mul(c.projection, view), eye: new Float32Array([eye[2], eye[0], eye[1]]) };
  }

  const api = {
    ready: null,
    load, loadBytes,
    info: () => info,
    state: () => JSON.parse(M.state()),
    runScript(text, options = {}) {
      const summary = JSON.parse(M.runScript(text, options.recordEvery || 1,
                                             options.showFrame === undefined ? -1 : options.showFrame));
      if (summary.error) throw new Error(summary.error);
      if (options.showFrame !== undefined) live = false;
      return { summary, frames: Array.from(M.recordedFrames()), positions: M.recordedPositions().slice() };
    },
    showLive() { M.showLive(); live = true; last = 0; },
    // Draws the shown frame once: through `camera` (glTF axes, see above) or the player's own,
    // unlit (the blended key textures only, as fourd-play's render draws them) on a transparent
    // background, or as the page draws it.
    render(options = {}) {
      const width = options.width || canvas.width, height = options.height || canvas.height;
      resize(width, height);
      uploadShape();
      if (options.camera) {
        const { vp, eye } = cameraViewProjection(options.camera);
        gl.viewport(0, 0, width, height);
        gl.clearColor(0, 0, 0, 0);
        gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
        gl.enable(gl.DEPTH_TEST);
        drawCharacter(vp, eye, options.unlit);
      } else {
        drawScene(width, height);
      }
      return canvas.toDataURL('image/png');
    },
    // Live play for `seconds` at width x height: frames drawn per second of wall-clock time
    // (requestAnimationFrame waits for the GPU to take the previous frame, so this is the rate
    // the frames are rendered at), and the mean JavaScript time of a frame (runtime step,
    // upload, draw calls).
    async measureFps(seconds, width, height) {
      api.showLive();
      fixedSize = [width, height];
      measuring = true;
      const work = [];
      const steps = [];
      let frames = 0;
      const start = performance.now();
      await new Promise((resolve) => {
        function measured(now) {
          const t0 = performance.now();
          tick(now);
          work.push(performance.now() - t0);
          steps.push(stepMs);
          ++frames;
          if (performance.now() - start < 1000 * seconds) requestAnimationFrame(measured);
          else resolve();
        }
        requestAnimationFrame(measured);
      });
      const elapsed = (performance.now() - start) / 1000;
      fixedSize = null;
      measuring = false;
      return { frames, seconds: elapsed, fps: frames / elapsed, frame_work_ms: mean(work),
               step_ms: mean(steps), width, height, state: JSON.parse(M.state()) };
    },
    benchmark: (steps = 2000, dt = 1 / 60, evictMb = 0) => JSON.parse(M.benchmark(steps, dt, evictMb)),
  };
  window.fourd = api;
  api.ready = createFourdModule().then(async (module) => {
    M = module;
    hud.textContent = 'no asset: pick a .fourd file, or open this page with ?asset=URL';
    requestAnimationFrame(loop);
    const url = new URLSearchParams(location.search).get('asset');
    if (url) {
      try { await load(url); } catch (e) { fail(e.message); }
    }
    return api;
  });
})();
