// The Isaac viewer: plays a run's trajectory with the scene's camera and lights (the drawing itself: draw.js,
// shared with the live page of `isaac live`). Written for Isaac, no library. The page fetches nothing unless it is
// served live by `isaac watch`.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const canvas = $("view");
  const params = new URLSearchParams(location.hash.slice(1));

  let model = null; // the decoded scene and trajectory (see load)
  let t = 0; // the time shown, s
  let playing = false;
  let speed = 1;
  let lastNow = null;
  let dirty = true;

  const D = IsaacDraw;
  const renderer = new D.Renderer(canvas);
  const orbit = D.newOrbit();

  // ---- data -------------------------------------------------------------------------------------------------

  function load(data) {
    const model = D.loadModel(data);
    const time = D.decode(data.time, Float64Array);
    return Object.assign(model, {
      time: time,
      position: D.decode(data.position, Float32Array),
      orientation: D.decode(data.orientation, Float32Array),
      start: data.start,
      end: time.length ? Math.max(time[time.length - 1], data.start) : data.start,
      sceneEnd: data.end,
    });
  }

  // one frame: every body and the mechanism at time t, seen by the current camera
  function draw() {
    if (!model || !model.time.length) { renderer.draw(null); return; }
    const poses = D.trajectoryPoses(model.time, model.position, model.orientation, model.bodies.length, t);
    renderer.draw(model, poses, t, currentCamera(), orbit, null);
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
    const [k] = D.frameAt(m.time, t);
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
    $("camera").addEventListener("change", () => { D.resetOrbit(orbit); dirty = true; });
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
    D.zoomControls(canvas, orbit, () => { dirty = true; });
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
