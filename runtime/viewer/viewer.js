// The Isaac viewer: plays a run's trajectory with the scene's camera and lights. Written for Isaac, no library.
//
// Rendering is Canvas2D, not WebGL: each frame the bodies' triangles (tessellated by isaac_runtime.export.geometry
// and embedded in this page) are moved by the trajectory's poses, shaded flat (Lambert, one colour per triangle)
// by the scene's lights, clipped at the near plane, sorted far to near (painter's algorithm) and filled. That needs
// no GPU (headless browsers and remote desktops often have none, and WebGL then falls back or fails) and no
// third-party code; scenes of a few thousand triangles draw at display rate. Planes are drawn first, under
// everything. The page fetches nothing unless it is served live by `isaac watch`.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const canvas = $("view");
  const ctx = canvas.getContext("2d");
  const params = new URLSearchParams(location.hash.slice(1));
  const NEAR = 0.01; // m: the near clipping plane
  const BACKGROUND = "#262a31";

  let model = null; // the decoded scene and trajectory (see load)
  let t = 0; // the time shown, s
  let playing = false;
  let speed = 1;
  let lastNow = null;
  let dirty = true;
  let orbit = { azimuth: 0, elevation: 0, zoom: 1 };

  // ---- data -------------------------------------------------------------------------------------------------

  function decode(text, Type) {
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  function load(data) {
    const bodies = data.bodies.map((b) => ({
      name: b.name,
      color: b.color,
      plane: b.shape === "plane",
      twoSided: b.two_sided,
      local: decode(b.positions, Float32Array),
      triangles: decode(b.triangles, Uint32Array),
      tone: b.tone ? decode(b.tone, Uint8Array) : null,
    }));
    const time = decode(data.time, Float64Array);
    return {
      data: data,
      bodies: bodies,
      time: time,
      position: decode(data.position, Float32Array),
      orientation: decode(data.orientation, Float32Array),
      start: data.start,
      end: time.length ? Math.max(time[time.length - 1], data.start) : data.start,
      sceneEnd: data.end,
      camera: data.cameras[0],
    };
  }

  // ---- poses ------------------------------------------------------------------------------------------------

  // frame k and weight a so that t lies between time[k] and time[k+1] (a in [0, 1])
  function frameAt(time, t) {
    const n = time.length;
    if (n === 0) return [0, 0];
    if (t <= time[0]) return [0, 0];
    if (t >= time[n - 1]) return [n - 1, 0];
    let lo = 0, hi = n - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (time[mid] <= t) lo = mid; else hi = mid;
    }
    return [lo, (t - time[lo]) / (time[hi] - time[lo])];
  }

  // position (3) and rotation matrix (9, row-major) of body b at time t: linear / normalized-lerp between frames
  function pose(m, b, t) {
    const B = m.bodies.length;
    const [k, a] = frameAt(m.time, t);
    const k1 = Math.min(k + 1, m.time.length - 1);
    const p = [0, 0, 0];
    for (let i = 0; i < 3; i++) {
      p[i] = (1 - a) * m.position[(k * B + b) * 3 + i] + a * m.position[(k1 * B + b) * 3 + i];
    }
    const q0 = m.orientation.subarray((k * B + b) * 4, (k * B + b) * 4 + 4);
    const q1 = m.orientation.subarray((k1 * B + b) * 4, (k1 * B + b) * 4 + 4);
    const sign = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0 ? -1 : 1;
    const q = [0, 0, 0, 0];
    for (let i = 0; i < 4; i++) q[i] = (1 - a) * q0[i] + a * sign * q1[i];
    const n = Math.hypot(q[0], q[1], q[2], q[3]) || 1;
    const [w, x, y, z] = q.map((v) => v / n);
    // R = I + 2 w [v]x + 2 [v]x^2 (as isaac_runtime.rotation.quat_to_matrix)
    const R = [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
               2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
               2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)];
    return [p, R];
  }

  // ---- camera -----------------------------------------------------------------------------------------------

  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const unit = (a) => { const n = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / n, a[1] / n, a[2] / n]; };

  // the eye after the user's orbit (drag) and zoom (wheel) about the camera's look-at point
  function eyeOf(cam) {
    const target = cam.look_at;
    const back = sub(cam.position, target);
    const up = unit(cam.up);
    const r = Math.hypot(back[0], back[1], back[2]) * orbit.zoom;
    let side = cross(up, back);
    if (Math.hypot(side[0], side[1], side[2]) < 1e-9) side = cross(up, [1, 0, 0]);
    side = unit(side);
    const fwd = unit(cross(side, up)); // horizontal, from the target toward the eye
    const elev0 = Math.asin(Math.max(-1, Math.min(1, dot(unit(back), up))));
    const el = Math.max(-1.5, Math.min(1.5, elev0 + orbit.elevation));
    const az = orbit.azimuth;
    const c = Math.cos(el), s = Math.sin(el);
    const dir = [0, 1, 2].map((i) => c * (Math.cos(az) * fwd[i] + Math.sin(az) * side[i]) + s * up[i]);
    return [target[0] + r * dir[0], target[1] + r * dir[1], target[2] + r * dir[2]];
  }

  // world-to-camera rows (s, u, -f) and the eye, as gluLookAt (isaac_runtime.export.geometry.look_at_matrix)
  function view(cam) {
    const eye = eyeOf(cam);
    const f = unit(sub(cam.look_at, eye));
    let s = cross(f, cam.up);
    if (Math.hypot(s[0], s[1], s[2]) < 1e-9) s = cross(f, [1, 0, 0]);
    s = unit(s);
    const u = cross(s, f);
    return { eye: eye, rows: [s, u, [-f[0], -f[1], -f[2]]] };
  }

  // ---- shading ----------------------------------------------------------------------------------------------

  // light of a surface point with unit normal n at world point c: an (r, g, b) multiplier
  function lightAt(lights, n, c, eye) {
    const out = [0.12, 0.12, 0.12]; // a little ambient so that nothing is black
    const add = (k, color) => { for (let i = 0; i < 3; i++) out[i] += k * color[i]; };
    if (!lights.length) { // no lights in the scene: a headlight
      add(0.85 * Math.max(0, dot(n, unit(sub(eye, c)))), [1, 1, 1]);
    }
    for (const l of lights) {
      if (l.type === "ambient") { add(l.intensity, l.color); continue; }
      const toLight = l.type === "distant" ? unit(sub(l.position, l.target)) : unit(sub(l.position, c));
      let k = l.intensity * Math.max(0, dot(n, toLight));
      if (l.type === "spot") {
        const axis = unit(sub(l.target, l.position));
        const cosAngle = -dot(toLight, axis);
        k *= cosAngle >= Math.cos(l.cone || 0.5236) ? 1 : 0;
      }
      add(k, l.color);
    }
    return out;
  }

  function css(rgb) {
    const c = (v) => Math.round(255 * Math.max(0, Math.min(1, v)));
    return "rgb(" + c(rgb[0]) + "," + c(rgb[1]) + "," + c(rgb[2]) + ")";
  }

  // ---- drawing ----------------------------------------------------------------------------------------------

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(canvas.clientWidth * dpr), h = Math.round(canvas.clientHeight * dpr);
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; dirty = true; }
  }

  // one frame: the polygons of every body and nail at time t, seen by the current camera, painted far to near
  function draw() {
    resize();
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (!model || !model.time.length) return;
    const cam = currentCamera();
    const v = view(cam);
    const f = 1 / Math.tan(cam.fov / 2), W = canvas.width, H = canvas.height;
    // camera space -> pixels: perspective with the vertical field of view
    v.toScreen = (q) => [(f * H / W * q[0] / -q[2] + 1) * W / 2, (1 - f * q[1] / -q[2]) * H / 2];
    const polygons = [];
    model.bodies.forEach((body, b) => bodyPolygons(body, b, v, polygons));
    rodPolygons(v, polygons);
    polygons.sort((p, q) => p.layer - q.layer || p.depth - q.depth); // planes first, then far to near
    paint(polygons);
  }

  // the visible, shaded, near-clipped triangles of body b, appended to out
  function bodyPolygons(body, b, v, out) {
    const [p, R] = pose(model, b, t);
    const L = body.local, n = L.length / 3;
    const world = new Float64Array(L.length), cam3 = new Float64Array(L.length);
    for (let i = 0; i < n; i++) {
      const x = L[3 * i], y = L[3 * i + 1], z = L[3 * i + 2];
      for (let r = 0; r < 3; r++) world[3 * i + r] = R[3 * r] * x + R[3 * r + 1] * y + R[3 * r + 2] * z + p[r];
      const d = [world[3 * i] - v.eye[0], world[3 * i + 1] - v.eye[1], world[3 * i + 2] - v.eye[2]];
      for (let r = 0; r < 3; r++) cam3[3 * i + r] = dot(v.rows[r], d);
    }
    const T = body.triangles;
    for (let k = 0; k < T.length; k += 3) {
      const ia = 3 * T[k], ib = 3 * T[k + 1], ic = 3 * T[k + 2];
      const a = [world[ia], world[ia + 1], world[ia + 2]];
      const e1 = [world[ib] - a[0], world[ib + 1] - a[1], world[ib + 2] - a[2]];
      const e2 = [world[ic] - a[0], world[ic + 1] - a[1], world[ic + 2] - a[2]];
      let normal = unit(cross(e1, e2));
      if (dot(normal, sub(v.eye, a)) <= 0) {
        if (!body.twoSided) continue; // the back of a closed surface
        normal = [-normal[0], -normal[1], -normal[2]];
      }
      const centre = [a[0] + (e1[0] + e2[0]) / 3, a[1] + (e1[1] + e2[1]) / 3, a[2] + (e1[2] + e2[2]) / 3];
      const light = lightAt(model.data.lights, normal, centre, v.eye);
      const tone = body.tone && body.tone[k / 3] ? 0.82 : 1;
      const rgb = [0, 1, 2].map((i) => body.color[i] * light[i] * tone);
      const pts = clip([[cam3[ia], cam3[ia + 1], cam3[ia + 2]], [cam3[ib], cam3[ib + 1], cam3[ib + 2]],
                        [cam3[ic], cam3[ic + 1], cam3[ic + 2]]]);
      if (pts.length < 3) continue;
      const depth = pts.reduce((sum, q) => sum + q[2], 0) / pts.length;
      out.push({ layer: body.plane ? 0 : 1, depth: depth, screen: pts.map(v.toScreen), fill: css(rgb) });
    }
  }

  // nails, while active: a rod from the body's centre to its nailed point, appended to out
  function rodPolygons(v, out) {
    for (const link of model.data.links || []) {
      if (t < link.start || t > link.end) continue;
      const [p, R] = pose(model, link.body, t);
      const q = link.point;
      const a = [0, 1, 2].map((r) => R[3 * r] * q[0] + R[3 * r + 1] * q[1] + R[3 * r + 2] * q[2] + p[r]);
      const ends = clipSegment(...[p, a].map((w) => v.rows.map((row) => dot(row, sub(w, v.eye)))));
      if (!ends.length) continue;
      out.push({ layer: 1, depth: (ends[0][2] + ends[1][2]) / 2, screen: ends.map(v.toScreen), line: true,
                 fill: "#d0d4da" });
    }
  }

  function paint(polygons) {
    ctx.lineJoin = "round";
    for (const poly of polygons) {
      const s = poly.screen;
      ctx.beginPath();
      ctx.moveTo(s[0][0], s[0][1]);
      for (let i = 1; i < s.length; i++) ctx.lineTo(s[i][0], s[i][1]);
      ctx.strokeStyle = ctx.fillStyle = poly.fill;
      if (poly.line) { // a rod, and a square for its nail
        ctx.lineWidth = 1.5;
        ctx.stroke();
        ctx.fillRect(s[1][0] - 2.5, s[1][1] - 2.5, 5, 5);
        continue;
      }
      ctx.closePath();
      ctx.lineWidth = 0.8; // the outline covers the hairline seams between neighbouring triangles
      ctx.fill();
      ctx.stroke();
    }
  }

  // Sutherland-Hodgman against the near plane z = -NEAR (camera space; visible points have z < -NEAR)
  function clip(pts) {
    const inside = (q) => q[2] <= -NEAR;
    if (pts.every(inside)) return pts;
    const out = [];
    for (let i = 0; i < pts.length; i++) {
      const a = pts[i], b = pts[(i + 1) % pts.length];
      if (inside(a)) out.push(a);
      if (inside(a) !== inside(b)) {
        const s = (-NEAR - a[2]) / (b[2] - a[2]);
        out.push([a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), -NEAR]);
      }
    }
    return out;
  }

  function clipSegment(a, b) {
    const ia = a[2] <= -NEAR, ib = b[2] <= -NEAR;
    if (ia && ib) return [a, b];
    if (!ia && !ib) return [];
    const s = (-NEAR - a[2]) / (b[2] - a[2]);
    const x = [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), -NEAR];
    return ia ? [a, x] : [x, b];
  }

  // ---- controls and clock ----------------------------------------------------------------------------------

  const audio = $("audio");
  const slider = $("timeline");

  function currentCamera() {
    const cams = model.data.cameras;
    return cams.find((c) => c.name === $("camera").value) || cams[0];
  }

  // the audio starts at the scene's start time; it is the clock while it plays at the chosen speed
  function audioClock() {
    return audio.src && !audio.paused && !audio.ended && audio.readyState >= 2;
  }

  function seek(time) {
    t = Math.max(model.start, Math.min(model.end, time));
    if (audio.src && audio.readyState >= 1) {
      const at = t - model.start;
      if (at < (audio.duration || 0)) { if (Math.abs(audio.currentTime - at) > 0.02) audio.currentTime = at; }
      else if (!audio.paused) audio.pause();
    }
    dirty = true;
  }

  function setPlaying(on) {
    playing = on;
    $("play").textContent = on ? "\u275a\u275a" : "\u25b6";
    $("play").title = on ? "pause (space)" : "play (space)";
    if (!audio.src) return;
    if (on && t - model.start < (audio.duration || Infinity)) {
      audio.currentTime = t - model.start;
      audio.playbackRate = speed;
      audio.play().catch(() => {}); // refused without a user gesture: the picture plays on its own clock
    } else {
      audio.pause();
    }
  }

  function tick(now) {
    if (playing && lastNow !== null) {
      if (audioClock()) t = model.start + audio.currentTime;
      else t += (now - lastNow) / 1000 * speed;
      if (t >= model.end) {
        if ($("loop").checked) { t = model.start; if (audio.src) { audio.currentTime = 0; setPlaying(true); } }
        else { t = model.end; setPlaying(false); }
      }
      dirty = true;
    }
    lastNow = now;
    if (dirty) { draw(); showTime(); dirty = false; }
    requestAnimationFrame(tick);
  }

  function showTime() {
    const m = model;
    const span = m.end - m.start || 1;
    if (document.activeElement !== slider) slider.value = String(Math.round(1000 * (t - m.start) / span));
    $("clock").textContent = "t = " + t.toFixed(3) + " s / " + m.sceneEnd.toFixed(2) + " s";
    const [k] = frameAt(m.time, t);
    document.body.dataset.time = t.toFixed(6);
    document.body.dataset.frame = String(k);
  }

  function bindControls() {
    $("play").addEventListener("click", () => setPlaying(!playing));
    slider.addEventListener("input", () => seek(model.start + (model.end - model.start) * slider.value / 1000));
    $("speed").addEventListener("change", () => {
      speed = parseFloat($("speed").value);
      if (audio.src) audio.playbackRate = speed;
    });
    $("camera").addEventListener("change", () => { orbit = { azimuth: 0, elevation: 0, zoom: 1 }; dirty = true; });
    document.addEventListener("keydown", (e) => {
      if (e.target.tagName === "SELECT") return;
      const step = model.time.length > 1 ? model.time[1] - model.time[0] : 0.01;
      if (e.key === " ") { setPlaying(!playing); e.preventDefault(); }
      else if (e.key === "ArrowRight") seek(t + step);
      else if (e.key === "ArrowLeft") seek(t - step);
      else if (e.key === "Home") seek(model.start);
    });
    let drag = null;
    canvas.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener("pointerup", () => { drag = null; });
    canvas.addEventListener("pointermove", (e) => {
      if (!drag) return;
      orbit.azimuth -= (e.clientX - drag[0]) * 0.01;
      orbit.elevation += (e.clientY - drag[1]) * 0.01;
      drag = [e.clientX, e.clientY];
      dirty = true;
    });
    canvas.addEventListener("wheel", (e) => {
      orbit.zoom *= Math.exp(e.deltaY * 0.001);
      dirty = true;
      e.preventDefault();
    }, { passive: false });
    canvas.addEventListener("dblclick", () => { orbit = { azimuth: 0, elevation: 0, zoom: 1 }; dirty = true; });
    window.addEventListener("resize", () => { dirty = true; });
  }

  function install(data) {
    model = load(data);
    const select = $("camera");
    const keep = select.value;
    select.innerHTML = "";
    for (const c of data.cameras) {
      const option = document.createElement("option");
      option.value = option.textContent = c.name;
      select.appendChild(option);
    }
    if (data.cameras.some((c) => c.name === keep)) select.value = keep;
    select.hidden = data.cameras.length < 2;
    $("title").textContent = data.scene;
    document.body.dataset.result = String(data.result);
    $("note").textContent = data.note || "";
    if (data.audio) {
      if (audio.getAttribute("src") !== data.audio) audio.src = data.audio;
      document.body.dataset.audio = "yes";
    } else {
      audio.removeAttribute("src");
      document.body.dataset.audio = "no";
    }
    $("sound").textContent = data.audio ? "\u266a sound" : "";
    t = Math.max(model.start, Math.min(model.end, t));
    dirty = true;
  }

  // ---- live: `isaac watch` serves this page and says when a new result is ready ------------------------------

  function live(data) {
    let result = data.result;
    let busy = false;
    async function poll() {
      if (busy) return;
      busy = true;
      try {
        const status = await (await fetch("status.json", { cache: "no-store" })).json();
        $("status").textContent = status.message || "";
        $("status").className = status.state;
        $("diagnostic").textContent = status.diagnostic || "";
        $("diagnostic").hidden = !status.diagnostic;
        if (status.result !== result) {
          const next = await (await fetch("data.json?result=" + status.result, { cache: "no-store" })).json();
          result = next.result;
          install(next);
        }
      } catch (e) {
        $("status").textContent = "watch stopped: showing the last result";
        $("status").className = "stopped";
      }
      busy = false;
    }
    setInterval(poll, 250);
    poll();
  }

  // ---- start ------------------------------------------------------------------------------------------------

  const data = JSON.parse($("isaac-data").textContent);
  bindControls();
  install(data);
  if (params.get("ui") === "0") document.body.classList.add("bare");
  if (params.has("speed")) { speed = parseFloat(params.get("speed")) || 1; $("speed").value = String(speed); }
  if (params.has("camera")) $("camera").value = params.get("camera");
  seek(params.has("t") ? parseFloat(params.get("t")) : model.start);
  draw(); // at once, so that a screenshot taken on load shows the requested time
  showTime();
  dirty = false;
  document.body.dataset.ready = "1";
  audio.addEventListener("loadedmetadata", () => { document.body.dataset.audioDuration = audio.duration.toFixed(3); });
  if (params.get("play") === "1") setPlaying(true);
  if (data.live) live(data);
  requestAnimationFrame(tick);
})();
