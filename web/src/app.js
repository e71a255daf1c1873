// The linecloud console: maps, their line clouds in 3D, photos localized
// through the API, and the owner's audit. Talks only to linecloud serve's API
// (docs/http_api.md) with the bearer token the user gives.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const state = { token: sessionStorage.getItem("linecloud-token") || "", map: null, view: null };

function setStatus(text, isError = false) {
  $("status").textContent = text;
  $("status").className = isError ? "error" : "";
}

// One API call: JSON (or bytes) back, or an Error with the server's message.
async function api(path, { method = "GET", body = null, binary = false } = {}) {
  const headers = state.token ? { Authorization: `Bearer ${state.token}` } : {};
  const res = await fetch(path, { method, body, headers });
  if (!res.ok) {
    let message = `${res.status} ${res.statusText}`;
    try { message = `${res.status}: ${(await res.json()).error}`; } catch { /* not JSON */ }
    const error = new Error(message);
    error.status = res.status;
    throw error;
  }
  return binary ? { bytes: await res.arrayBuffer(), headers: res.headers } : res.json();
}

// ---- maps -----------------------------------------------------------------

async function signIn(token) {
  state.token = token;
  sessionStorage.setItem("linecloud-token", token);
  $("maps").replaceChildren();
  try {
    const { maps } = await api("/v1/maps");
    for (const m of maps) {
      const li = document.createElement("li");
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = `${m.id} — ${m.lines.toLocaleString("en")} lines`;
      b.dataset.map = m.id;
      b.setAttribute("aria-pressed", "false");
      b.addEventListener("click", () => openMap(m.id));
      li.append(b);
      $("maps").append(li);
    }
    setStatus(maps.length ? `${maps.length} map(s) for this token` : "no map for this token");
  } catch (e) {
    setStatus(`Sign-in failed: ${e.message}`, true);
  }
}

function describe(dl, rows) {
  dl.replaceChildren();
  for (const [key, text, value] of rows) {
    const dt = document.createElement("dt");
    dt.textContent = key;
    const dd = document.createElement("dd");
    dd.textContent = text;
    if (value !== undefined) dd.dataset.value = JSON.stringify(value);
    dd.id = `${dl.id}-${key.replace(/\W+/g, "-")}`;
    dl.append(dt, dd);
  }
}

async function openMap(id) {
  state.map = id;
  for (const b of $("maps").querySelectorAll("button")) {
    b.setAttribute("aria-pressed", String(b.dataset.map === id));
  }
  try {
    const info = await api(`/v1/maps/${encodeURIComponent(id)}`);
    const dl = document.createElement("dl");
    dl.id = "info";
    describe(dl, [
      ["map", info.id],
      ["lines", info.num_lines.toLocaleString("en")],
      ["encoding", info.encoding],
      ["descriptors", info.has_descriptors ? `${info.descriptors.dim}-D ${info.descriptors.type}` : "none"],
      ["gravity", info.gravity ? info.gravity.map((v) => v.toFixed(3)).join(", ") : "unknown"],
      ["geo-anchor", info.geo_anchor ? JSON.stringify(info.geo_anchor.geo_anchor) : "none"],
      ["key", info.key_fingerprint],
    ]);
    $("map-info").replaceChildren(dl);
    await loadSegments();
    await loadAudit(id);
    setStatus(`map ${id} open`);
  } catch (e) {
    setStatus(`Map ${id}: ${e.message}`, true);
  }
}

async function loadAudit(id) {
  $("audit").hidden = true;
  try {
    const report = await api(`/v1/maps/${encodeURIComponent(id)}/audit`);
    const rec = report.density_attack?.recovery;
    if (!rec) return;
    const table = $("audit-shares");
    table.replaceChildren();
    const head = table.insertRow();
    for (const t of ["within (of the scene diagonal)", "share of the points"]) {
      const th = document.createElement("th");
      th.textContent = t;
      head.append(th);
    }
    const shares = Object.entries(rec.within_diagonal_percent).sort((a, b) => Number(a[0]) - Number(b[0]));
    for (const [pct, share] of shares) {
      const row = table.insertRow();
      row.insertCell().textContent = `${pct} %`;
      row.insertCell().textContent = `${(100 * share).toFixed(1)} %`;
    }
    $("audit").hidden = false;
    await loadRecoveredPoints(id);
  } catch (e) {
    if (e.status !== 404) setStatus(`Audit: ${e.message}`, true);
  }
}

// The points the audit's attack recovered, coloured by their error (the
// audit's colours), beside the lines.
async function loadRecoveredPoints(id) {
  const view = state.view;
  if (view?.recovered) {
    view.scene.remove(view.recovered);
    view.recovered = null;
  }
  $("audit-points-count").textContent = "";
  let answer;
  try {
    answer = await api(`/v1/maps/${encodeURIComponent(id)}/audit/points`, { binary: true });
  } catch (e) {
    if (e.status === 404) return;
    throw e;
  }
  const n = Number(answer.headers.get("X-Linecloud-Points"));
  $("audit-points-count").textContent = `${n.toLocaleString("en")} points recovered by the attack`;
  if (!view) return;
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(answer.bytes, 0, 3 * n), 3));
  geometry.setAttribute("color", new THREE.BufferAttribute(new Uint8Array(answer.bytes, 12 * n, 3 * n), 3, true));
  view.recovered = new THREE.Points(geometry, new THREE.PointsMaterial({ size: 4, sizeAttenuation: false, vertexColors: true, depthTest: false }));
  view.recovered.visible = $("show-recovered").checked;
  view.scene.add(view.recovered);
  view.dirty = true;
}

// ---- the 3D view ----------------------------------------------------------

function webglAvailable() {
  try {
    const c = document.createElement("canvas");
    return !!(c.getContext("webgl2") || c.getContext("webgl"));
  } catch {
    return false;
  }
}

function makeView() {
  if (state.view || !webglAvailable()) {
    if (!state.view) $("webgl-missing").hidden = false;
    return state.view;
  }
  const el = $("view");
  const renderer = new THREE.WebGLRenderer({ antialias: false, powerPreference: "high-performance" });
  renderer.setPixelRatio(1);
  renderer.setSize(el.clientWidth, el.clientHeight);
  el.append(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(50, el.clientWidth / el.clientHeight, 0.01, 1e6);
  const controls = new OrbitControls(camera, renderer.domElement);
  el.addEventListener("keydown", (ev) => {
    const step = { ArrowLeft: [0.05, 0], ArrowRight: [-0.05, 0], ArrowUp: [0, 0.05], ArrowDown: [0, -0.05] }[ev.key];
    if (!step) return;
    const offset = camera.position.clone().sub(controls.target);
    const s = new THREE.Spherical().setFromVector3(offset);
    s.theta += step[0];
    s.phi = Math.min(Math.PI - 0.01, Math.max(0.01, s.phi + step[1]));
    camera.position.copy(controls.target).add(new THREE.Vector3().setFromSpherical(s));
    view.dirty = true;
    ev.preventDefault();
  });
  // Drawn when something changed: an idle console costs no CPU.
  const view = { renderer, scene, camera, controls, lines: null, frustum: null, radius: 1, dirty: true };
  controls.addEventListener("change", () => { view.dirty = true; });
  const loop = () => {
    controls.update();
    if (view.dirty) {
      view.dirty = false;
      renderer.render(scene, camera);
    }
    requestAnimationFrame(loop);
  };
  requestAnimationFrame(loop);
  state.view = view;
  return view;
}

async function loadSegments() {
  const limit = Math.max(100, Number($("limit").value) || 2000);
  const { bytes, headers } = await api(`/v1/maps/${encodeURIComponent(state.map)}/segments?limit=${limit}`,
                                       { binary: true });
  const total = Number(headers.get("X-Linecloud-Lines"));
  const shown = Number(headers.get("X-Linecloud-Segments"));
  $("view-count").textContent = `${shown.toLocaleString("en")} of ${total.toLocaleString("en")} lines shown` +
                                (shown < total ? " (a fixed random subset)" : "");
  const view = makeView();
  if (!view) return;
  if (view.lines) view.scene.remove(view.lines);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(bytes), 3));
  geometry.computeBoundingSphere();
  view.lines = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0x3d79a8 }));
  view.scene.add(view.lines);
  const { center, radius } = geometry.boundingSphere;
  view.radius = radius || 1;
  view.controls.target.copy(center);
  view.camera.position.copy(center).add(new THREE.Vector3(0, -0.3 * radius, 1.6 * radius));
  view.camera.near = radius / 1000;
  view.camera.far = radius * 100;
  view.camera.updateProjectionMatrix();
  view.dirty = true;
}

// Pixel statistics of the view, drawn and read in one go (the browser test
// checks that the canvas is not blank): share of lit pixels, mean, std.
window.linecloudViewPixels = () => {
  const view = state.view;
  if (!view) return null;
  view.renderer.render(view.scene, view.camera);
  const gl = view.renderer.domElement;
  const c = document.createElement("canvas");
  c.width = gl.width;
  c.height = gl.height;
  const ctx = c.getContext("2d");
  ctx.drawImage(gl, 0, 0);
  const d = ctx.getImageData(0, 0, c.width, c.height).data;
  let lit = 0, sum = 0, sum2 = 0;
  for (let i = 0; i < d.length; i += 4) {
    const v = d[i] + d[i + 1] + d[i + 2];
    lit += v > 30 ? 1 : 0;
    sum += v;
    sum2 += v * v;
  }
  const n = d.length / 4, mean = sum / n;
  return { lit: lit / n, mean, std: Math.sqrt(sum2 / n - mean * mean) };
};

// Frames per second the renderer draws while the view turns: each frame is
// drawn and waited for (a one-pixel read), so the figure is the drawing's own
// cost, not the browser's frame scheduling (headless chromium's emulated
// vsync stalls software rendering). The browser test reads it.
window.linecloudFps = async (ms = 2000) => {
  const view = state.view;
  if (!view) return 0;
  const gl = view.renderer.getContext();
  const pixel = new Uint8Array(4);
  const axis = new THREE.Vector3(0, 1, 0);
  let frames = 0;
  const t0 = performance.now();
  while (performance.now() - t0 < ms) {
    view.camera.position.sub(view.controls.target).applyAxisAngle(axis, 0.02).add(view.controls.target);
    view.camera.lookAt(view.controls.target);
    view.renderer.render(view.scene, view.camera);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    frames += 1;
    if (frames % 10 === 0) await new Promise((r) => setTimeout(r, 0));  // stay responsive
  }
  view.dirty = true;
  return frames / ((performance.now() - t0) / 1000);
};

// ---- localizing a photo ---------------------------------------------------

function quatToMatrix([w, x, y, z]) {
  return new THREE.Matrix4().makeRotationFromQuaternion(new THREE.Quaternion(x, y, z, w));
}

// The camera's frustum (cam_from_world q, t) in the map frame.
function showFrustum(result, cameraText) {
  const view = state.view;
  if (!view) return;
  if (view.frustum) view.scene.remove(view.frustum);
  const [model, w, h, ...p] = cameraText.trim().split(/\s+/);
  const simple = model.startsWith("SIMPLE") || model === "RADIAL";
  const fx = Number(p[0]), fy = simple ? fx : Number(p[1]);
  const cx = Number(simple ? p[1] : p[2]), cy = Number(simple ? p[2] : p[3]);
  const worldFromCam = quatToMatrix(result.q).transpose();
  const centre = new THREE.Vector3(...result.center);
  const depth = 0.15 * view.radius;
  const corners = [[0, 0], [Number(w), 0], [Number(w), Number(h)], [0, Number(h)]].map(([u, v]) =>
    new THREE.Vector3((u - cx) / fx, (v - cy) / fy, 1).multiplyScalar(depth).applyMatrix4(worldFromCam).add(centre));
  const points = [];
  for (let i = 0; i < 4; ++i) points.push(centre, corners[i], corners[i], corners[(i + 1) % 4]);
  view.frustum = new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(points),
                                        new THREE.LineBasicMaterial({ color: 0xffe066, depthTest: false }));
  view.scene.add(view.frustum);
  view.dirty = true;
}

async function drawOverlay(file, result) {
  const bitmap = await createImageBitmap(file);
  const canvas = $("overlay");
  const scale = Math.min(1, 640 / bitmap.width);
  canvas.width = Math.round(bitmap.width * scale);
  canvas.height = Math.round(bitmap.height * scale);
  const ctx = canvas.getContext("2d");
  ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  ctx.strokeStyle = "#3ddc84";
  for (const [x, y] of result.inlier_keypoints || []) {
    ctx.beginPath();
    ctx.arc((x - 0.5) * scale, (y - 0.5) * scale, 2.5, 0, 2 * Math.PI);  // COLMAP's pixel centres
    ctx.stroke();
  }
}

function rememberCamera(text) {
  const recent = JSON.parse(localStorage.getItem("linecloud-cameras") || "[]").filter((c) => c !== text);
  recent.unshift(text);
  localStorage.setItem("linecloud-cameras", JSON.stringify(recent.slice(0, 8)));
  fillRecentCameras();
}

function fillRecentCameras() {
  const list = $("recent-cameras");
  list.replaceChildren();
  for (const c of JSON.parse(localStorage.getItem("linecloud-cameras") || "[]")) {
    const o = document.createElement("option");
    o.value = c;
    list.append(o);
  }
}

async function localize(file) {
  if (!state.map) return setStatus("open a map first", true);
  if (!file) return setStatus("choose a photo", true);
  const cameraText = $("camera").value.trim();
  if (!cameraText) return setStatus("give the photo's camera", true);
  const form = new FormData();
  form.append("image", file, file.name);
  form.append("camera", cameraText);
  setStatus(`localizing ${file.name} ...`);
  try {
    const r = await api(`/v1/maps/${encodeURIComponent(state.map)}/localize`, { method: "POST", body: form });
    rememberCamera(cameraText);
    if (!r.success) {
      describe($("pose"), [["success", "no pose", false], ["reason", r.reason]]);
      setStatus(`no pose: ${r.reason}`, true);
      return;
    }
    const f = (v) => v.map((x) => x.toFixed(6)).join(", ");
    const t = r.times_ms;
    describe($("pose"), [
      ["success", "pose found", true],
      ["q", f(r.q), r.q],
      ["t", f(r.t), r.t],
      ["center", f(r.center), r.center],
      ["inliers", `${r.num_inliers} of ${r.num_matches} matches (${(100 * r.inlier_ratio).toFixed(1)} %)`, r.num_inliers],
      ["uncertainty", `${r.uncertainty.rotation_deg.toFixed(4)}°, ${r.uncertainty.position.toFixed(4)} map units`],
      ["times", `decode ${t.decode.toFixed(0)} · extract ${t.extract.toFixed(0)} · match ${t.match.toFixed(0)} · RANSAC ${t.ransac.toFixed(1)} · total ${t.total.toFixed(0)} ms`],
    ]);
    showFrustum(r, cameraText);
    await drawOverlay(file, r);
    setStatus(`${file.name}: localized`);
  } catch (e) {
    setStatus(`Localize: ${e.message}`, true);
  }
}

// ---- wiring ---------------------------------------------------------------

$("login").addEventListener("submit", (ev) => {
  ev.preventDefault();
  signIn($("token").value.trim());
});
$("localize").addEventListener("submit", (ev) => {
  ev.preventDefault();
  localize($("photo").files[0]);
});
$("limit").addEventListener("change", () => state.map && loadSegments().catch((e) => setStatus(e.message, true)));
const drop = $("drop");
drop.addEventListener("dragover", (ev) => { ev.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (ev) => {
  ev.preventDefault();
  drop.classList.remove("over");
  localize(ev.dataTransfer.files[0]);
});
drop.addEventListener("keydown", (ev) => { if (ev.key === "Enter" || ev.key === " ") $("photo").click(); });
$("show-recovered").addEventListener("change", () => {
  if (state.view?.recovered) {
    state.view.recovered.visible = $("show-recovered").checked;
    state.view.dirty = true;
  }
});
fillRecentCameras();
$("token").value = state.token;
if (!webglAvailable()) $("webgl-missing").hidden = false;
