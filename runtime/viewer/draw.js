// The Isaac drawing: a scene's bodies and mechanism at given poses, seen by its camera, lit by its lights.
// Written for Isaac, no library. Shared by the offline viewer (viewer.js: viewer.html of `isaac run`, the page of
// `isaac watch`) and the live page of `isaac live` (live.js).
//
// Rendering is Canvas2D, not WebGL: each frame the bodies' triangles (tessellated by isaac_runtime.export.geometry
// and embedded in the page) are moved by the poses, shaded flat (Lambert, one colour per triangle) by the scene's
// lights, clipped at the near plane, sorted far to near (painter's algorithm) and filled. That needs no GPU
// (headless browsers and remote desktops often have none) and no third-party code. Under the bodies: the ground
// (a static plane facing up, or a floor below the scene) with a grid fading toward its edge, and the bodies'
// shadows cast on it by the key light (the first distant light, else a point or spot light, else straight down),
// blurred by each body's height above the ground (soft shadows). With the bodies: the wires of nails and ball
// joints from each body's surface to its anchor (a mobile's rods and discs hang by them), a dot at each joint,
// a hinge's axis, springs as coils, dampers as rods, ropes; gear teeth are part of the gears' surfaces.
"use strict";

var IsaacDraw = (function () {
  const NEAR = 0.01; // m: the near clipping plane
  const BACKGROUND = "#262a31";
  const SHADOW_ALPHA = 0.45;
  const PENUMBRA = 0.015; // the shadow's blur, as a fraction of the body's height above the ground (+ a little)

  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (k, a) => [k * a[0], k * a[1], k * a[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => Math.hypot(a[0], a[1], a[2]);
  const unit = (a) => { const n = norm(a) || 1; return [a[0] / n, a[1] / n, a[2] / n]; };

  // ---- data -------------------------------------------------------------------------------------------------

  function decode(text, Type) {
    const bin = atob(text || "");
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  // the page's data, decoded once: bodies' surfaces in their own frames, and the mechanism as given
  function loadModel(data) {
    return {
      data: data,
      bodies: data.bodies.map((b) => ({
        name: b.name, color: b.color, motion: b.motion, plane: b.shape === "plane", twoSided: b.two_sided,
        local: decode(b.positions, Float32Array), triangles: decode(b.triangles, Uint32Array),
        tone: b.tone ? decode(b.tone, Uint8Array) : null,
      })),
      ground: data.ground || null,
    };
  }

  // ---- poses: [position (3), rotation matrix (9, row-major)] per body --------------------------------------

  function quatMatrix(w, x, y, z) {
    const n = Math.hypot(w, x, y, z) || 1;
    w /= n; x /= n; y /= n; z /= n;
    // R = I + 2 w [v]x + 2 [v]x^2 (as isaac_runtime.core.rotation.quat_to_matrix)
    return [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)];
  }

  // frame k and weight a so that t lies between time[k] and time[k+1] (a in [0, 1])
  function frameAt(time, t) {
    const n = time.length;
    if (n === 0 || t <= time[0]) return [0, 0];
    if (t >= time[n - 1]) return [n - 1, 0];
    let lo = 0, hi = n - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (time[mid] <= t) lo = mid; else hi = mid;
    }
    return [lo, (t - time[lo]) / (time[hi] - time[lo])];
  }

  // every body's pose at time t of a trajectory (position (T*B*3), orientation (T*B*4)): linear / normalized lerp
  function trajectoryPoses(time, position, orientation, B, t) {
    const [k, a] = frameAt(time, t);
    const k1 = Math.min(k + 1, time.length - 1);
    const poses = [];
    for (let b = 0; b < B; b++) {
      const p = [0, 1, 2].map((i) => (1 - a) * position[(k * B + b) * 3 + i] + a * position[(k1 * B + b) * 3 + i]);
      const q0 = orientation.subarray((k * B + b) * 4, (k * B + b) * 4 + 4);
      const q1 = orientation.subarray((k1 * B + b) * 4, (k1 * B + b) * 4 + 4);
      const sign = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0 ? -1 : 1;
      const q = [0, 1, 2, 3].map((i) => (1 - a) * q0[i] + a * sign * q1[i]);
      poses.push([p, quatMatrix(q[0], q[1], q[2], q[3])]);
    }
    return poses;
  }

  function framePoses(position, orientation, B) {
    return trajectoryPoses([0], position, orientation, B, 0);
  }

  const apply = (pose, q) => {
    const [p, R] = pose;
    return [0, 1, 2].map((r) => R[3 * r] * q[0] + R[3 * r + 1] * q[1] + R[3 * r + 2] * q[2] + p[r]);
  };
  const applyT = (pose, w) => { // the body-frame point of world point w: R^T (w - p)
    const [p, R] = pose, d = sub(w, p);
    return [0, 1, 2].map((c) => R[c] * d[0] + R[3 + c] * d[1] + R[6 + c] * d[2]);
  };
  const rotate = (pose, q) => { const R = pose[1]; return [0, 1, 2].map((r) => dot(R.slice(3 * r, 3 * r + 3), q)); };
  // a point of body b (its frame), or a world point for b = -1
  const pointOf = (poses, b, q) => (b < 0 ? q : apply(poses[b], q));

  // ---- camera -----------------------------------------------------------------------------------------------

  // the eye after the user's orbit (drag) and zoom (wheel) about the camera's look-at point
  function eyeOf(cam, orbit) {
    const target = cam.look_at, back = sub(cam.position, target), up = unit(cam.up);
    const r = norm(back) * orbit.zoom;
    let side = cross(up, back);
    if (norm(side) < 1e-9) side = cross(up, [1, 0, 0]);
    side = unit(side);
    const fwd = unit(cross(side, up)); // horizontal, from the target toward the eye
    const elev0 = Math.asin(Math.max(-1, Math.min(1, dot(unit(back), up))));
    const el = Math.max(-1.5, Math.min(1.5, elev0 + orbit.elevation));
    const az = orbit.azimuth, c = Math.cos(el), s = Math.sin(el);
    const dir = [0, 1, 2].map((i) => c * (Math.cos(az) * fwd[i] + Math.sin(az) * side[i]) + s * up[i]);
    return add(target, scale(r, dir));
  }

  // world-to-camera rows (s, u, -f), the eye, and camera space -> pixels (perspective, vertical field of view)
  function viewOf(cam, orbit, W, H) {
    const eye = eyeOf(cam, orbit);
    const f = unit(sub(cam.look_at, eye));
    let s = cross(f, cam.up);
    if (norm(s) < 1e-9) s = cross(f, [1, 0, 0]);
    s = unit(s);
    const u = cross(s, f), k = 1 / Math.tan(cam.fov / 2);
    const v = { eye: eye, rows: [s, u, [-f[0], -f[1], -f[2]]], k: k, W: W, H: H };
    v.toCamera = (w) => { const d = sub(w, eye); return [dot(s, d), dot(u, d), -dot(f, d)]; };
    v.toScreen = (q) => [(k * H / W * q[0] / -q[2] + 1) * W / 2, (1 - k * q[1] / -q[2]) * H / 2];
    v.ray = (x, y) => { // the world direction through pixel (x, y)
      const c = [(2 * x / W - 1) * W / (k * H), (1 - 2 * y / H) / k, -1];
      return unit([0, 1, 2].map((i) => s[i] * c[0] + u[i] * c[1] - f[i] * c[2]));
    };
    v.forward = f;
    return v;
  }

  // ---- shading ----------------------------------------------------------------------------------------------

  // light of a surface point with unit normal n at world point c: an (r, g, b) multiplier
  function lightAt(lights, n, c, eye) {
    const out = [0.12, 0.12, 0.12]; // a little ambient so that nothing is black
    const addLight = (k, color) => { for (let i = 0; i < 3; i++) out[i] += k * color[i]; };
    if (!lights.length) addLight(0.85 * Math.max(0, dot(n, unit(sub(eye, c)))), [1, 1, 1]); // a headlight
    for (const l of lights) {
      if (l.type === "ambient") { addLight(l.intensity, l.color); continue; }
      const toLight = l.type === "distant" ? unit(sub(l.position, l.target)) : unit(sub(l.position, c));
      let k = l.intensity * Math.max(0, dot(n, toLight));
      if (l.type === "spot") k *= -dot(toLight, unit(sub(l.target, l.position))) >= Math.cos(l.cone || 0.5236) ? 1 : 0;
      addLight(k, l.color);
    }
    return out;
  }

  function css(rgb, alpha) {
    const c = (v) => Math.round(255 * Math.max(0, Math.min(1, v)));
    const body = c(rgb[0]) + "," + c(rgb[1]) + "," + c(rgb[2]);
    return alpha === undefined ? "rgb(" + body + ")" : "rgba(" + body + "," + alpha.toFixed(3) + ")";
  }

  // ---- clipping ---------------------------------------------------------------------------------------------

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

  // ---- the renderer -----------------------------------------------------------------------------------------

  function Renderer(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.shadowCanvas = document.createElement("canvas");
    this.world = []; // each body's world vertices at the last draw (for picking)
    this.view = null;
    this.poses = null;
  }

  Renderer.prototype.resize = function () {
    const c = this.canvas, dpr = window.devicePixelRatio || 1;
    const w = Math.round(c.clientWidth * dpr), h = Math.round(c.clientHeight * dpr);
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; return true; }
    return false;
  };

  // one picture: the model at the poses, at time t (for the constraints' windows), seen by cam after orbit;
  // overlay: {from, to} world points of a drag's spring, drawn over everything
  Renderer.prototype.draw = function (model, poses, t, cam, orbit, overlay) {
    this.resize();
    const ctx = this.ctx, W = this.canvas.width, H = this.canvas.height;
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, W, H);
    if (!model || !cam || !poses || poses.length !== model.bodies.length) return;
    const v = viewOf(cam, orbit, W, H);
    this.view = v;
    this.poses = poses;
    const under = [], items = [];
    this.world = model.bodies.map((body, b) => bodyPolygons(body, poses[b], v, model.data.lights,
                                                           body.plane ? under : items));
    mechanismItems(model.data, poses, t, v, items);
    under.sort((p, q) => p.depth - q.depth);
    paint(ctx, under);
    if (model.ground) {
      if (model.ground.plane < 0) groundGrid(ctx, model.ground, v); // (a plane has its own checker)
      this.shadows(model, v);
    }
    items.sort((p, q) => p.depth - q.depth); // far to near (depths are negative)
    paint(ctx, items);
    if (overlay) paintDrag(ctx, v, overlay);
  };

  // the triangles of a body at its pose: shaded, near-clipped and projected, appended to out; its world vertices
  function bodyPolygons(body, pose, v, lights, out) {
    const [p, R] = pose, L = body.local, n = L.length / 3;
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
        normal = scale(-1, normal);
      }
      const centre = [a[0] + (e1[0] + e2[0]) / 3, a[1] + (e1[1] + e2[1]) / 3, a[2] + (e1[2] + e2[2]) / 3];
      const light = lightAt(lights, normal, centre, v.eye);
      const tone = body.tone && body.tone[k / 3] ? 0.82 : 1;
      const rgb = [0, 1, 2].map((i) => body.color[i] * light[i] * tone);
      const pts = clip([[cam3[ia], cam3[ia + 1], cam3[ia + 2]], [cam3[ib], cam3[ib + 1], cam3[ib + 2]],
                        [cam3[ic], cam3[ic + 1], cam3[ic + 2]]]);
      if (pts.length < 3) continue;
      const depth = pts.reduce((sum, q) => sum + q[2], 0) / pts.length;
      out.push({ depth: depth, screen: pts.map(v.toScreen), fill: css(rgb) });
    }
    return world;
  }

  // ---- the mechanism: wires, joints, axes, springs, ropes ---------------------------------------------------

  function mechanismItems(data, poses, t, v, out) {
    const active = (x) => t >= x.start && t <= x.end;
    const line = (a, b, color, width) => {
      const ends = clipSegment(v.toCamera(a), v.toCamera(b));
      if (ends.length) {
        out.push({ depth: (ends[0][2] + ends[1][2]) / 2, screen: ends.map(v.toScreen), line: true,
                   fill: color, width: width || 1.5 });
      }
    };
    const mark = (w, shape, color, size) => {
      const q = v.toCamera(w);
      if (q[2] <= -NEAR) out.push({ depth: q[2] + 1e-4, screen: [v.toScreen(q)], mark: shape, fill: color, size: size });
    };
    for (const link of data.links || []) { // nails: a wire from the surface to the nailed point, and the nail
      if (!active(link)) continue;
      const pose = poses[link.body];
      line(apply(pose, link.attach || [0, 0, 0]), apply(pose, link.point), "#d0d4da");
      mark(link.target, "square", "#d0d4da", 5);
    }
    for (const joint of data.joints || []) { // ball joints: each body's wire to its anchor, a dot where they meet
      if (!active(joint)) continue;
      for (const end of joint.ends) line(apply(poses[end.body], end.attach), apply(poses[end.body], end.anchor), "#c9ced6", 1.2);
      const first = joint.ends[0], anchor = apply(poses[first.body], first.anchor);
      if (joint.axis) {
        const half = scale(joint.size / 2, unit(rotate(poses[first.body], joint.axis)));
        line(sub(anchor, half), add(anchor, half), "#e8e2c8", 3);
      }
      mark(anchor, "dot", "#eceff3", 3.2);
    }
    for (const spring of data.springs || []) {
      const a = pointOf(poses, spring.bodies[0], spring.points[0]), b = pointOf(poses, spring.bodies[1], spring.points[1]);
      if (spring.type === "damper") { line(a, b, "#9aa3ad", 4); continue; }
      coil(a, b).forEach((p, i, all) => { if (i) line(all[i - 1], p, "#e0b050", 1.4); });
      mark(a, "dot", "#e0b050", 2.5);
      mark(b, "dot", "#e0b050", 2.5);
    }
    for (const rope of data.ropes || []) {
      if (!active(rope)) continue;
      const rim = add(poses[rope.gear][0], rope.arm);
      line(rim, sub(poses[rope.weight][0], scale(rope.reach, rope.direction)), "#d9c7a0", 1.2);
    }
  }

  // points of a helix from a to b: 8 turns, radius a twelfth of the length (at least 1 cm), straight ends
  function coil(a, b) {
    const d = sub(b, a), length = norm(d) || 1e-9, axis = scale(1 / length, d);
    let e1 = cross(axis, [0, 1, 0]);
    if (norm(e1) < 1e-6) e1 = cross(axis, [1, 0, 0]);
    e1 = unit(e1);
    const e2 = cross(axis, e1), r = Math.max(0.01, length / 12), turns = 8, per = 10, lead = 0.1;
    const out = [a];
    for (let i = 0; i <= turns * per; i++) {
      const s = lead + (1 - 2 * lead) * i / (turns * per), phi = 2 * Math.PI * i / per;
      out.push(add(add(a, scale(s * length, axis)), add(scale(r * Math.cos(phi), e1), scale(r * Math.sin(phi), e2))));
    }
    out.push(b);
    return out;
  }

  // ---- the ground: grid and shadows --------------------------------------------------------------------------

  function groundAxes(g) {
    const n = unit(g.normal);
    const u = unit(cross(n, Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 0, 1]));
    return [n, u, cross(n, u)];
  }

  // a floor a little lighter than the background, fading toward its edge, and lines every `spacing` across a
  // square of `size` about the scene's centre, fading too
  function groundGrid(ctx, g, v) {
    const [, u, w] = groundAxes(g), half = g.size / 2, count = Math.floor(half / g.spacing), pieces = 24;
    const at = (x, y) => add(g.centre, add(scale(x, u), scale(y, w)));
    const fade = (x, y) => Math.max(0, 1 - (x * x + y * y) / (half * half));
    const tile = g.size / pieces;
    for (let i = 0; i < pieces; i++) {
      for (let j = 0; j < pieces; j++) {
        const x0 = -half + i * tile, y0 = -half + j * tile, a = fade(x0 + tile / 2, y0 + tile / 2);
        if (a <= 0) continue;
        const pts = clip([at(x0, y0), at(x0 + tile, y0), at(x0 + tile, y0 + tile), at(x0, y0 + tile)].map(v.toCamera));
        if (pts.length < 3) continue;
        const s = pts.map(v.toScreen);
        ctx.fillStyle = "rgba(255,255,255," + (0.07 * a).toFixed(4) + ")";
        ctx.beginPath();
        ctx.moveTo(s[0][0], s[0][1]);
        for (let k = 1; k < s.length; k++) ctx.lineTo(s[k][0], s[k][1]);
        ctx.closePath();
        ctx.fill();
      }
    }
    ctx.lineWidth = 1;
    for (const [a, b] of [[u, w], [w, u]]) {
      for (let i = -count; i <= count; i++) {
        for (let k = 0; k < pieces; k++) {
          const s0 = -half + g.size * k / pieces, s1 = s0 + g.size / pieces, r = fade(i * g.spacing, (s0 + s1) / 2);
          if (r <= 0) continue;
          const p0 = add(add(g.centre, scale(i * g.spacing, b)), scale(s0, a));
          const p1 = add(add(g.centre, scale(i * g.spacing, b)), scale(s1, a));
          const ends = clipSegment(v.toCamera(p0), v.toCamera(p1));
          if (!ends.length) continue;
          const [q0, q1] = ends.map(v.toScreen);
          ctx.strokeStyle = "rgba(205,212,222," + (0.2 * r).toFixed(3) + ")";
          ctx.beginPath();
          ctx.moveTo(q0[0], q0[1]);
          ctx.lineTo(q1[0], q1[1]);
          ctx.stroke();
        }
      }
    }
  }

  // the key light for shadows: {dir} toward a distant light, {at} a point or spot light; without either, a
  // light from above and a little in front (from the scene's first camera), so that shadows fall behind the bodies
  function keyLight(lights, g, cam) {
    for (const l of lights) if (l.type === "distant") return { dir: unit(sub(l.position, l.target)) };
    for (const l of lights) if (l.type === "point" || l.type === "spot") return { at: l.position };
    const n = unit(g.normal);
    if (!cam) return { dir: n };
    const toward = sub(cam.position, g.centre), level = sub(toward, scale(dot(toward, n), n));
    return { dir: unit(add(n, scale(0.45, unit(level)))) };
  }

  // world point w cast onto the ground by the light, or null when the light cannot cast it there
  function castOn(g, n, light, w) {
    if (light.dir) {
      const k = dot(light.dir, n);
      if (k < 0.05) return null;
      return sub(w, scale(dot(sub(w, g.point), n) / k, light.dir));
    }
    const d = sub(w, light.at), k = dot(d, n);
    if (k >= -1e-9) return null; // the point is not below the light
    return add(light.at, scale(dot(sub(g.point, light.at), n) / k, d));
  }

  Renderer.prototype.shadows = function (model, v) {
    const g = model.ground, [n] = groundAxes(g), light = keyLight(model.data.lights, g, model.data.cameras[0]);
    const sc = this.shadowCanvas;
    if (sc.width !== v.W || sc.height !== v.H) { sc.width = v.W; sc.height = v.H; }
    const sctx = sc.getContext("2d");
    sctx.clearRect(0, 0, v.W, v.H);
    sctx.fillStyle = "#000";
    let any = false;
    model.bodies.forEach((body, b) => {
      if (body.plane) return;
      const world = this.world[b], T = body.triangles, path = new Path2D();
      let height = 0, count = 0, depth = 0;
      const cast = [];
      for (let i = 0; i < world.length; i += 3) {
        const w = [world[i], world[i + 1], world[i + 2]], s = castOn(g, n, light, w);
        cast.push(s && v.toCamera(s));
        if (s) { height += dot(sub(w, g.point), n); depth += cast[cast.length - 1][2]; count++; }
      }
      if (!count || height / count < 0) return;
      for (let k = 0; k < T.length; k += 3) {
        const tri = [cast[T[k]], cast[T[k + 1]], cast[T[k + 2]]];
        if (tri.some((q) => !q)) continue;
        const pts = clip(tri);
        if (pts.length < 3) continue;
        const s = pts.map(v.toScreen);
        // one turning sense for all (a closed surface cast flat has as many triangles of each sense: under the
        // non-zero rule they would cancel)
        if ((s[1][0] - s[0][0]) * (s[2][1] - s[0][1]) - (s[1][1] - s[0][1]) * (s[2][0] - s[0][0]) < 0) s.reverse();
        path.moveTo(s[0][0], s[0][1]);
        for (let i = 1; i < s.length; i++) path.lineTo(s[i][0], s[i][1]);
        path.closePath();
      }
      // the blur: the penumbra's width at that height, in pixels at the shadow's depth
      const metres = 0.01 + PENUMBRA * height / count;
      const pixels = Math.min(40, Math.max(1, metres * v.k * v.H / 2 / Math.max(1e-3, -depth / count)));
      sctx.filter = "blur(" + pixels.toFixed(1) + "px)";
      sctx.fill(path);
      any = true;
    });
    sctx.filter = "none";
    if (!any) return;
    const ctx = this.ctx;
    ctx.globalAlpha = SHADOW_ALPHA;
    ctx.drawImage(sc, 0, 0);
    ctx.globalAlpha = 1;
  };

  // ---- painting ----------------------------------------------------------------------------------------------

  function paint(ctx, items) {
    ctx.lineJoin = "round";
    for (const item of items) {
      const s = item.screen;
      ctx.strokeStyle = ctx.fillStyle = item.fill;
      if (item.mark) {
        const r = item.size;
        ctx.beginPath();
        if (item.mark === "dot") ctx.arc(s[0][0], s[0][1], r, 0, 2 * Math.PI);
        else ctx.rect(s[0][0] - r / 2, s[0][1] - r / 2, r, r);
        ctx.fill();
        continue;
      }
      ctx.beginPath();
      ctx.moveTo(s[0][0], s[0][1]);
      for (let i = 1; i < s.length; i++) ctx.lineTo(s[i][0], s[i][1]);
      if (item.line) {
        ctx.lineWidth = item.width;
        ctx.stroke();
        continue;
      }
      ctx.closePath();
      ctx.lineWidth = 0.8; // the outline covers the hairline seams between neighbouring triangles
      ctx.fill();
      ctx.stroke();
    }
  }

  function paintDrag(ctx, v, overlay) {
    const a = clipSegment(v.toCamera(overlay.from), v.toCamera(overlay.to));
    if (!a.length) return;
    const [p, q] = a.map(v.toScreen);
    ctx.strokeStyle = ctx.fillStyle = "#ff6e6e";
    ctx.lineWidth = 2;
    ctx.setLineDash([6, 4]);
    ctx.beginPath();
    ctx.moveTo(p[0], p[1]);
    ctx.lineTo(q[0], q[1]);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.beginPath();
    ctx.arc(q[0], q[1], 4, 0, 2 * Math.PI);
    ctx.fill();
  }

  // ---- picking: the body under a pixel (Moller-Trumbore against its triangles at the last draw) ------------

  // {body, local (its frame), world, distance} of the nearest body surface under pixel (x, y), or null
  Renderer.prototype.pick = function (model, x, y, wanted) {
    const v = this.view;
    if (!v || !this.poses) return null;
    const dpr = window.devicePixelRatio || 1, dir = v.ray(x * dpr, y * dpr), o = v.eye;
    let best = null;
    model.bodies.forEach((body, b) => {
      if (wanted && !wanted(body)) return;
      const world = this.world[b], T = body.triangles;
      for (let k = 0; k < T.length; k += 3) {
        const a = world.subarray(3 * T[k], 3 * T[k] + 3), p1 = world.subarray(3 * T[k + 1], 3 * T[k + 1] + 3);
        const p2 = world.subarray(3 * T[k + 2], 3 * T[k + 2] + 3);
        const e1 = sub(p1, a), e2 = sub(p2, a), h = cross(dir, e2), det = dot(e1, h);
        if (Math.abs(det) < 1e-12) continue;
        const s = sub(o, a), uu = dot(s, h) / det;
        if (uu < 0 || uu > 1) continue;
        const qv = cross(s, e1), vv = dot(dir, qv) / det;
        if (vv < 0 || uu + vv > 1) continue;
        const d = dot(e2, qv) / det;
        if (d > NEAR && (!best || d < best.distance)) best = { body: b, distance: d };
      }
    });
    if (!best) return null;
    best.world = add(o, scale(best.distance, dir));
    best.local = applyT(this.poses[best.body], best.world);
    return best;
  };

  // where the ray through pixel (x, y) meets the plane through `point` facing the camera
  Renderer.prototype.onViewPlane = function (point, x, y) {
    const v = this.view, dpr = window.devicePixelRatio || 1, dir = v.ray(x * dpr, y * dpr);
    const k = dot(dir, v.forward);
    if (Math.abs(k) < 1e-6) return point;
    return add(v.eye, scale(dot(sub(point, v.eye), v.forward) / k, dir));
  };

  // ---- the orbit both pages turn the camera by: the wheel zooms, a double click goes back home ----------------

  function newOrbit() { return { azimuth: 0, elevation: 0, zoom: 1 }; }
  function resetOrbit(orbit) { Object.assign(orbit, newOrbit()); }

  // changed() is called after every change of the orbit or of the window's size (the page redraws)
  function zoomControls(canvas, orbit, changed) {
    canvas.addEventListener("wheel", (e) => {
      orbit.zoom *= Math.exp(e.deltaY * 0.001);
      changed();
      e.preventDefault();
    }, { passive: false });
    canvas.addEventListener("dblclick", () => { resetOrbit(orbit); changed(); });
    window.addEventListener("resize", changed);
  }

  return { decode: decode, loadModel: loadModel, frameAt: frameAt, trajectoryPoses: trajectoryPoses,
           framePoses: framePoses, apply: apply, Renderer: Renderer, BACKGROUND: BACKGROUND, newOrbit: newOrbit,
           resetOrbit: resetOrbit, zoomControls: zoomControls };
})();
