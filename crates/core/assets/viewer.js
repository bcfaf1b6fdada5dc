// primfit view: a small WebGL 2 viewer of a scan and its fitted primitives (MIT OR
// Apache-2.0, part of primfit). Reads the JSON of <script id="primfit-data"> (written by
// primfit-core render/html.rs): positions are float32 relative to `origin`, base64.
// Reports its state in <body data-status="loading|ok|error"> and #status, which the
// headless-browser test reads.
"use strict";
(function () {
  const statusEl = document.getElementById("status");
  const problems = [];
  function setStatus(state, text) {
    document.body.dataset.status = state;
    statusEl.textContent = text;
  }
  function fail(message) {
    problems.push(String(message));
    setStatus("error", "error: " + problems.join("; "));
  }
  window.addEventListener("error", (e) => fail(e.message || e));
  window.addEventListener("unhandledrejection", (e) => fail(e.reason));
  const consoleError = console.error.bind(console);
  console.error = (...args) => {
    fail(args.join(" "));
    consoleError(...args);
  };

  const data = JSON.parse(document.getElementById("primfit-data").textContent);
  function bytes(b64) {
    const s = atob(b64);
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
    return out;
  }
  const floats = (b64) => new Float32Array(bytes(b64).buffer);
  const indices = (b64) => new Uint32Array(bytes(b64).buffer);

  // Viridis at 0, 0.1, ..., 1 (as render/colormap.rs), expanded to 256 entries.
  const VIRIDIS = [[68, 1, 84], [72, 36, 117], [65, 68, 135], [53, 95, 141], [42, 120, 142],
    [33, 145, 140], [34, 168, 132], [68, 191, 112], [122, 209, 81], [189, 223, 38], [253, 231, 37]];
  const LUT = new Uint8Array(256 * 3);
  for (let i = 0; i < 256; i++) {
    const x = (i / 255) * 10, k = Math.min(Math.floor(x), 9), f = x - k;
    for (let c = 0; c < 3; c++) LUT[3 * i + c] = Math.round(VIRIDIS[k][c] * (1 - f) + VIRIDIS[k + 1][c] * f);
  }

  // ---- the panel
  const points = data.points;
  document.title = data.title + " - primfit view";
  document.getElementById("title").textContent = data.title;
  document.getElementById("counts").textContent =
    `${points.count.toLocaleString()} of ${points.total.toLocaleString()} points shown` +
    `${points.count < points.total ? " (even subsample)" : ""}, ${data.primitives.length} primitives`;
  document.getElementById("scale").textContent = data.scale_label;
  const modeEl = document.getElementById("mode");
  const sizeEl = document.getElementById("size");
  if (!points.rgb) modeEl.querySelector('option[value="rgb"]').disabled = true;

  // ---- WebGL
  const canvas = document.getElementById("canvas");
  const gl = canvas.getContext("webgl2", { antialias: true });
  if (!gl) {
    fail("WebGL 2 is not available in this browser");
    return;
  }
  function compile(type, source) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  function program(vertex, fragment) {
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl.VERTEX_SHADER, vertex));
    gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fragment));
    gl.bindAttribLocation(p, 0, "pos");
    gl.bindAttribLocation(p, 1, "col");
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    const uniforms = {};
    for (let i = 0; i < gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS); i++) {
      const name = gl.getActiveUniform(p, i).name;
      uniforms[name] = gl.getUniformLocation(p, name);
    }
    return { p, u: uniforms };
  }
  const pointProgram = program(`#version 300 es
    in vec3 pos; in vec3 col; uniform mat4 mvp; uniform float size; uniform float bias;
    out vec3 vcol;
    void main() { gl_Position = mvp * vec4(pos, 1.0); gl_Position.z -= bias; gl_PointSize = size; vcol = col; }`,
  `#version 300 es
    precision mediump float; in vec3 vcol; out vec4 frag;
    void main() { frag = vec4(vcol, 1.0); }`);
  const meshProgram = program(`#version 300 es
    in vec3 pos; uniform mat4 mvp; uniform mat4 view; out vec3 eye;
    void main() { gl_Position = mvp * vec4(pos, 1.0); eye = (view * vec4(pos, 1.0)).xyz; }`,
  `#version 300 es
    precision highp float; in vec3 eye; uniform vec3 color; uniform vec3 light; out vec4 frag;
    void main() {
      vec3 n = normalize(cross(dFdx(eye), dFdy(eye)));
      frag = vec4(color * (0.3 + 0.7 * abs(dot(n, light))), 1.0);
    }`);

  function buffer(target, array) {
    const b = gl.createBuffer();
    gl.bindBuffer(target, b);
    gl.bufferData(target, array, gl.STATIC_DRAW);
    return b;
  }
  const pointVao = gl.createVertexArray();
  gl.bindVertexArray(pointVao);
  buffer(gl.ARRAY_BUFFER, floats(points.xyz));
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
  const colourBuffer = buffer(gl.ARRAY_BUFFER, new Uint8Array(3 * points.count));
  gl.enableVertexAttribArray(1);
  gl.vertexAttribPointer(1, 3, gl.UNSIGNED_BYTE, true, 0, 0);
  const error = bytes(points.error);
  const rgb = points.rgb ? bytes(points.rgb) : null;
  function colourPoints() {
    const mode = modeEl.value, c = new Uint8Array(3 * points.count);
    for (let i = 0; i < points.count; i++) {
      for (let k = 0; k < 3; k++) {
        c[3 * i + k] = mode === "rgb" && rgb ? rgb[3 * i + k] : mode === "grey" ? 110 : LUT[3 * error[i] + k];
      }
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, colourBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, c, gl.STATIC_DRAW);
  }
  colourPoints();

  const meshes = data.primitives.map((q) => {
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    buffer(gl.ARRAY_BUFFER, floats(q.xyz));
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    const faces = indices(q.faces);
    buffer(gl.ELEMENT_ARRAY_BUFFER, faces);
    return { vao, count: faces.length, color: q.color.map((c) => c / 255), visible: true };
  });
  gl.bindVertexArray(null);

  // ---- the primitive list
  const list = document.getElementById("prims");
  const boxes = data.primitives.map((q, k) => {
    const li = document.createElement("li");
    const box = document.createElement("input");
    box.type = "checkbox";
    box.checked = true;
    box.id = "prim" + k;
    box.addEventListener("change", () => { meshes[k].visible = box.checked; redraw(); });
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.background = `rgb(${q.color.join(",")})`;
    const label = document.createElement("label");
    label.htmlFor = box.id;
    label.textContent = `${k} ${q.type}` + (q.existence == null ? "" : ` (p = ${q.existence.toFixed(3)})`);
    li.append(box, swatch, label);
    list.append(li);
    return box;
  });
  function showAll(on) {
    boxes.forEach((b, k) => { b.checked = on; meshes[k].visible = on; });
    redraw();
  }
  document.getElementById("all").addEventListener("click", () => showAll(true));
  document.getElementById("none").addEventListener("click", () => showAll(false));
  modeEl.addEventListener("change", () => { colourPoints(); redraw(); });
  sizeEl.addEventListener("input", redraw);

  // ---- the camera: orthographic, orbiting `frame.up` (as render/camera.rs)
  const frame = data.frame;
  const home = () => ({ az: frame.azimuth, el: frame.elevation, target: frame.target.slice(), half: 0.55 * data.extent });
  let cam = home();
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const mix = (a, s, b, t) => [a[0] * s + b[0] * t, a[1] * s + b[1] * t, a[2] * s + b[2] * t];
  function basis() {
    const az = (cam.az * Math.PI) / 180, el = (cam.el * Math.PI) / 180;
    const side = cross(frame.up, frame.front);
    const horizontal = mix(frame.front, Math.cos(az), side, Math.sin(az));
    const back = mix(horizontal, Math.cos(el), frame.up, Math.sin(el));
    const right = mix(side, Math.cos(az), frame.front, -Math.sin(az));
    return { right, up: cross(back, right), back };
  }
  function matrices(aspect) {
    const { right, up, back } = basis();
    const t = cam.target, rows = [right, up, back];
    const view = new Float32Array(16);
    rows.forEach((r, k) => {
      for (let j = 0; j < 3; j++) view[4 * j + k] = r[j];
      view[12 + k] = -dot(r, t);
    });
    view[15] = 1;
    const scale = [1 / (cam.half * aspect), 1 / cam.half, -1 / (2 * data.extent)];
    const mvp = view.map((v, i) => (i % 4 < 3 ? v * scale[i % 4] : v));
    return { view, mvp, right, up };
  }

  function draw() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(246 / 255, 246 / 255, 246 / 255, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    const m = matrices(w / h);
    gl.useProgram(meshProgram.p);
    gl.uniformMatrix4fv(meshProgram.u.mvp, false, m.mvp);
    gl.uniformMatrix4fv(meshProgram.u.view, false, m.view);
    const l = [-0.4, 0.6, 1], n = Math.hypot(...l);
    gl.uniform3f(meshProgram.u.light, l[0] / n, l[1] / n, l[2] / n);
    for (const mesh of meshes) {
      if (!mesh.visible || mesh.count === 0) continue;
      gl.uniform3fv(meshProgram.u.color, mesh.color);
      gl.bindVertexArray(mesh.vao);
      gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_INT, 0);
    }
    if (modeEl.value !== "hidden" && points.count > 0) {
      gl.useProgram(pointProgram.p);
      gl.uniformMatrix4fv(pointProgram.u.mvp, false, m.mvp);
      gl.uniform1f(pointProgram.u.size, Number(sizeEl.value) * dpr);
      gl.uniform1f(pointProgram.u.bias, 0.01);
      gl.bindVertexArray(pointVao);
      gl.drawArrays(gl.POINTS, 0, points.count);
    }
    gl.bindVertexArray(null);
  }
  let pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; draw(); });
  }

  // ---- mouse: drag to orbit, shift- or right-drag to pan, wheel to zoom
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button !== 0 };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) {
      const { right, up } = basis(), k = (2 * cam.half) / canvas.clientHeight;
      cam.target = mix(mix(cam.target, 1, right, -dx * k), 1, up, dy * k);
    } else {
      cam.az -= dx * 0.4;
      cam.el = Math.max(-90, Math.min(90, cam.el + dy * 0.4));
    }
    redraw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    cam.half = Math.min(100 * data.extent, Math.max(1e-4 * data.extent, cam.half * Math.exp(e.deltaY * 0.001)));
    redraw();
  }, { passive: false });
  canvas.addEventListener("dblclick", () => { cam = home(); redraw(); });
  window.addEventListener("resize", redraw);

  // ---- first frame, checked: the test reads the status
  draw();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, px = new Uint8Array(4 * w * h);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let painted = 0;
  for (let i = 0; i < px.length; i += 4) {
    if (Math.abs(px[i] - 246) + Math.abs(px[i + 1] - 246) + Math.abs(px[i + 2] - 246) > 12) painted++;
  }
  if (problems.length === 0) {
    if (painted === 0) fail("the first frame is blank");
    else setStatus("ok", `ok: ${points.count} points, ${meshes.length} primitives, ${painted} pixels painted`);
  }
})();
