// The live page of `isaac live`: draws each pose as the server computes it (server-sent events from /events),
// plays the sound as it is rendered (Web Audio, each block scheduled after the last), shows the breath's level and
// the winds' speeds, and acts on the run: a drag on a body pulls it (POST /drag: the body, the picked point in its
// frame, the pointer's point in the world, on the plane through the picked point facing the camera; released on
// button up), a slider changes a declared parameter (POST /parameter, re-planned by the server). The drawing is
// draw.js's, the same as the offline viewer's. Written for Isaac, no library.
// What it has shown is kept on <body data-*> for tests and tools: ready, frames, frame, t, breath, wind (JSON),
// dragging, dragBody, audioBlocks, audioPlayed, audioSeconds, audioFrom, version, ended.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const D = IsaacDraw;
  const canvas = $("view");
  const renderer = new D.Renderer(canvas);
  const params = new URLSearchParams(location.hash.slice(1));
  const ds = document.body.dataset;

  let data = null, model = null, poses = null, t = 0, version = 0;
  const orbit = D.newOrbit();
  let dirty = true, frames = 0, ended = false;
  let drag = null; // {body, name, local, plane: world point the drag plane passes through, target}

  // ---- the scene ----------------------------------------------------------------------------------------------

  function install(next) {
    data = next;
    model = D.loadModel(data);
    poses = D.framePoses(D.decode(data.position, Float32Array), D.decode(data.orientation, Float32Array),
                         model.bodies.length);
    version = data.version || 0;
    t = data.start;
    $("title").textContent = data.scene;
    ds.version = String(version);
    if (drag && !model.bodies.some((b) => b.name === drag.name)) drag = null;
    dirty = true;
  }

  function camera() { return data.cameras[0]; }

  // ---- the stream ---------------------------------------------------------------------------------------------

  function connect() {
    const events = new EventSource("events?scene=" + version);
    events.addEventListener("frame", (e) => {
      const f = JSON.parse(e.data);
      if (f.version !== version) return; // a frame of a scene this page does not have yet
      poses = D.framePoses(D.decode(f.p, Float32Array), D.decode(f.q, Float32Array), model.bodies.length);
      t = f.t;
      frames++;
      showFrame(f);
      dirty = true;
    });
    events.addEventListener("scene", (e) => install(JSON.parse(e.data)));
    events.addEventListener("audio", (e) => play(JSON.parse(e.data)));
    events.addEventListener("notice", (e) => {
      const n = JSON.parse(e.data);
      $("notice").textContent = n.text;
      $("notice").className = n.level || "";
    });
    events.addEventListener("end", (e) => {
      const end = JSON.parse(e.data);
      ended = true;
      ds.ended = "1";
      $("state").textContent = end.error ? "stopped: " + end.error : "ended";
      $("state").className = end.error ? "error" : "ended";
      events.close();
    });
    events.onerror = () => {
      if (!ended) { $("state").textContent = "connection lost"; $("state").className = "error"; }
    };
  }

  function showFrame(f) {
    ds.frames = String(frames);
    ds.t = f.t.toFixed(4);
    ds.frame = String(f.k);
    $("clock").textContent = "t = " + f.t.toFixed(2) + " s / " + data.until.toFixed(2) + " s" +
      (f.lag_ms > 1 ? " \u00b7 " + f.lag_ms.toFixed(0) + " ms behind" : "");
    if (f.breath !== null && f.breath !== undefined) {
      $("level").style.width = Math.min(100, 100 * f.breath).toFixed(1) + "%";
      const source = data.breath ? " \u00b7 " + data.breath.name : "";
      $("breath-text").textContent = "level " + f.breath.toFixed(2) + source;
      ds.breath = f.breath.toFixed(4);
    }
    $("winds").textContent = (f.wind || []).map((w) => w.name + " " + w.speed.toFixed(2) + " m/s").join(", ");
    ds.wind = JSON.stringify(f.wind || []);
  }

  // ---- sound: each block scheduled right after the one before --------------------------------------------------

  let audio = null, playhead = 0, blocks = 0, scheduled = 0; // scheduled: s of sound

  function audioContext() {
    if (!audio && (window.AudioContext || window.webkitAudioContext)) {
      audio = new (window.AudioContext || window.webkitAudioContext)();
    }
    return audio;
  }

  function play(block) {
    blocks++;
    ds.audioBlocks = String(blocks);
    if (blocks === 1) ds.audioFrom = block.time.toFixed(4); // s: the scene time of the first block this page had
    const ctx = audioContext();
    if (!ctx) return;
    if (ctx.state !== "running") { $("sound").hidden = false; return; } // refused until the user asks
    const pcm = D.decode(block.pcm, Int16Array), n = pcm.length / block.channels;
    const buffer = ctx.createBuffer(block.channels, n, block.rate);
    for (let c = 0; c < block.channels; c++) {
      const out = buffer.getChannelData(c);
      for (let i = 0; i < n; i++) out[i] = pcm[i * block.channels + c] / 32768;
    }
    const source = ctx.createBufferSource();
    source.buffer = buffer;
    source.connect(ctx.destination);
    const when = Math.max(playhead, ctx.currentTime + 0.03);
    source.start(when);
    playhead = when + n / block.rate;
    ds.audioPlayed = String((Number(ds.audioPlayed) || 0) + 1);
    scheduled += n / block.rate;
    ds.audioSeconds = scheduled.toFixed(6);
  }

  $("sound").addEventListener("click", () => {
    const ctx = audioContext();
    if (ctx) ctx.resume().then(() => { $("sound").hidden = true; });
  });

  // ---- the mouse: drag a body, or turn the view ------------------------------------------------------------------

  let sending = false, queued = null;

  function post(route, body) {
    if (route === "drag" && sending) { queued = body; return; } // only the newest drag matters
    if (route === "drag") sending = true;
    fetch(route, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) })
      .catch(() => {})
      .finally(() => {
        if (route !== "drag") return;
        sending = false;
        if (queued) { const next = queued; queued = null; post("drag", next); }
      });
  }

  function sendDrag() {
    post("drag", { body: drag.name, point: drag.local, target: drag.target });
  }

  function bindMouse() {
    let turning = null;
    canvas.addEventListener("pointerdown", (e) => {
      canvas.setPointerCapture(e.pointerId);
      const hit = ended ? null : renderer.pick(model, e.offsetX, e.offsetY, (b) => b.motion !== "static" && !b.plane);
      if (hit) {
        drag = { body: hit.body, name: model.bodies[hit.body].name, local: hit.local, plane: hit.world,
                 target: hit.world };
        ds.dragging = "1";
        ds.dragBody = drag.name;
        sendDrag();
      } else {
        turning = [e.clientX, e.clientY];
      }
      dirty = true;
    });
    canvas.addEventListener("pointermove", (e) => {
      if (drag) {
        drag.target = renderer.onViewPlane(drag.plane, e.offsetX, e.offsetY);
        sendDrag();
        dirty = true;
      } else if (turning) {
        orbit.azimuth -= (e.clientX - turning[0]) * 0.01;
        orbit.elevation += (e.clientY - turning[1]) * 0.01;
        turning = [e.clientX, e.clientY];
        dirty = true;
      }
    });
    const up = () => {
      if (drag) { post("drag", { release: true }); drag = null; ds.dragging = "0"; }
      turning = null;
      dirty = true;
    };
    canvas.addEventListener("pointerup", up);
    canvas.addEventListener("pointercancel", up);
    D.zoomControls(canvas, orbit, () => { dirty = true; });
  }

  // ---- the parameters: a slider each, sent when let go ------------------------------------------------------------

  function buildSliders() {
    const box = $("sliders");
    box.innerHTML = "";
    $("sliders-title").hidden = !data.sliders.length;
    for (const s of data.sliders) {
      const row = document.createElement("div");
      row.className = "slider";
      const label = document.createElement("label");
      const name = document.createElement("span"), value = document.createElement("span");
      name.textContent = s.name;
      value.textContent = s.text;
      label.append(name, value);
      const input = document.createElement("input");
      Object.assign(input, { type: "range", min: s.min, max: s.max, step: s.step, value: s.value });
      input.dataset.name = s.name;
      const text = () => String(Number(Number(input.value).toPrecision(4))) + (s.unit ? " " + s.unit : "");
      input.addEventListener("input", () => { value.textContent = text(); });
      input.addEventListener("change", () => post("parameter", { name: s.name, value: text() }));
      row.append(label, input);
      box.appendChild(row);
    }
  }

  // ---- drawing ------------------------------------------------------------------------------------------------------

  function tick() {
    if (dirty && model) {
      const overlay = drag ? { from: D.apply(poses[drag.body], drag.local), to: drag.target } : null;
      renderer.draw(model, poses, t, camera(), orbit, overlay);
      dirty = false;
    }
    requestAnimationFrame(tick);
  }

  install(JSON.parse($("isaac-data").textContent));
  buildSliders();
  bindMouse();
  if (params.get("ui") === "0") document.body.classList.add("bare");
  if (!data.breath) $("breath-text").textContent = "no breath (isaac live SCENE --mic [DEVICE|FILE.wav])";
  connect();
  renderer.draw(model, poses, t, camera(), orbit, null);
  ds.ready = "1";
  requestAnimationFrame(tick);
})();
