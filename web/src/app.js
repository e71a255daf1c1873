// The linecloud console: maps, their line clouds in 3D, photos localized
// through the API, and the owner's audit. Talks only to linecloud serve's API
// (docs/http_api.md) with the bearer token the user gives.
//
// What is shown is what is open: the page keeps one state per token (session),
// per map and per request. Whatever was derived from one is cleared when it
// changes, and an answer that arrives for a token, map or request that is no
// longer current is dropped.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const $ = (id) => document.getElementById(id);
// The server's default --max-body-mb: larger photos are refused here, before the upload.
const MAX_PHOTO_BYTES = 16 * 1024 * 1024;
// The page's colours, defined once in style.css (--exact, --near, --far, --lines).
const colour = (name) => getComputedStyle(document.documentElement).getPropertyValue(`--${name}`).trim();
// The recovered points and the camera are drawn over the lines: like the lines
// transparent (three.js draws transparent objects after opaque ones, by
// renderOrder), never hidden by them.
const OVER_LINES = { transparent: true, opacity: 1, depthTest: false, depthWrite: false };
const RECOVERED_LINE_OPACITY = 0.2;
const state = {
  token: sessionStorage.getItem("linecloud-token") || "",
  session: 0, mapGen: 0, requestGen: 0,  // generations: an answer for an old one is dropped
  map: null, info: null, busy: false, pose: null, history: [], view: null, photo: null,
};

function setStatus(text) {
  $("status").textContent = text;
  $("error").textContent = "";
  $("photo-error").textContent = "";
}
function setError(text) {
  $("error").textContent = text;  // role="alert": announced
  $("status").textContent = "";
  $("photo-error").textContent = "";
}
// An error about the photo: also shown in the photo panel, where the user
// acted (on a phone the alert line is a screen or two above it).
function setPhotoError(text) {
  setError(text);
  $("photo-error").textContent = text;
}

// One API call: JSON (or bytes) back, or an Error with the server's message
// and, for 429 / 503, when to try again.
async function api(path, { method = "GET", body = null, binary = false } = {}) {
  const headers = state.token ? { Authorization: `Bearer ${state.token}` } : {};
  const res = await fetch(path, { method, body, headers });
  if (!res.ok) {
    let message = `${res.status} ${res.statusText}`;
    let serverMessage = "";
    try {
      serverMessage = (await res.json()).error;
      message = `${res.status}: ${serverMessage}`;
    } catch { /* not JSON */ }
    const retry = Number(res.headers.get("Retry-After"));
    if (retry > 0) message += ` — try again in ${Math.ceil(retry)} s`;
    const error = new Error(message);
    error.status = res.status;
    error.serverMessage = serverMessage;
    error.retryAfter = retry > 0 ? retry : null;
    throw error;
  }
  return binary ? { bytes: await res.arrayBuffer(), headers: res.headers } : res.json();
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

// ---- the three levels of state -------------------------------------------

function clearRequest() {
  state.requestGen += 1;
  state.pose = null;
  $("pose").replaceChildren();
  const canvas = $("overlay");
  canvas.hidden = true;
  canvas.width = canvas.height = 0;
  delete canvas.dataset.inliers;
  delete canvas.dataset.outliers;
  delete canvas.dataset.segments;
  delete canvas.dataset.orientation;
  $("overlay-legend").hidden = true;
  $("goto").disabled = true;
  removeFromView("frustum");
}

function clearMap() {
  state.mapGen += 1;
  state.map = null;
  state.info = null;
  clearRequest();
  $("map-info").replaceChildren();
  $("privacy").hidden = true;
  $("privacy-facts").replaceChildren();
  $("audit").hidden = true;
  $("audit-shares").replaceChildren();
  $("audit-points-count").textContent = "";
  $("view-count").textContent = "";
  $("view-note").textContent = "";
  for (const b of $("maps").querySelectorAll("button")) b.setAttribute("aria-pressed", "false");
  removeFromView("lines");
  removeFromView("recovered");
  updateTopButton();
}

function clearSession() {
  state.session += 1;
  clearMap();
  state.history = [];
  renderHistory();
  $("maps").replaceChildren();
}

// ---- maps -----------------------------------------------------------------

async function signIn(token) {
  clearSession();
  setStatus("signing in ...");  // and the last error gone
  const session = state.session;
  state.token = token;
  sessionStorage.removeItem("linecloud-token");
  try {
    const { maps } = await api("/v1/maps");
    if (session !== state.session) return;
    sessionStorage.setItem("linecloud-token", token);  // kept only once it worked
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
    $("logout-button").hidden = false;
    setStatus(maps.length ? `${maps.length} map(s) for this token` : "no map for this token");
  } catch (e) {
    if (session !== state.session) return;
    setError(e.status === 401
      ? "Sign-in failed: the service does not accept this token (401). Check it, or ask the service's operator for one."
      : `Sign-in failed: ${e.message}`);
  }
}

function signOut() {
  clearSession();
  state.token = "";
  sessionStorage.removeItem("linecloud-token");
  $("token").value = "";
  $("logout-button").hidden = true;
  setStatus("signed out");
}

async function openMap(id) {
  clearMap();
  setStatus(`opening map ${id} ...`);
  const gen = state.mapGen;
  state.map = id;
  for (const b of $("maps").querySelectorAll("button")) {
    b.setAttribute("aria-pressed", String(b.dataset.map === id));
  }
  try {
    const info = await api(`/v1/maps/${encodeURIComponent(id)}`);
    if (gen !== state.mapGen) return;
    state.info = info;
    const dl = document.createElement("dl");
    dl.id = "info";
    describe(dl, [
      ["map", info.id],
      ["lines", info.num_lines.toLocaleString("en")],
      ["encoding", info.encoding],
      ["descriptors", info.has_descriptors ? `${info.descriptors.dim}-D ${info.descriptors.type}` : "none"],
      ["gravity", info.gravity ? info.gravity.map((v) => v.toFixed(3)).join(", ") : "unknown"],
      ["geo-anchor", info.geo_anchor ? `${info.geo_anchor.lat.toFixed(6)}°, ${info.geo_anchor.lon.toFixed(6)}°, ${info.geo_anchor.h.toFixed(1)} m` : "none"],
      ["key", info.key_fingerprint],
    ]);
    $("map-info").replaceChildren(dl);
    updateTopButton();
    showPrivacy(info, null);
    // What this token may fetch (older servers do not say: then asked, and a 403 / 404 read).
    const may = info.for_this_token ?? { segments: true, audit: true, audit_points: true };
    if (may.segments) await loadSegments(gen);
    else $("view-note").textContent = NO_LINES_NOTE;
    if (may.audit) await loadAudit(id, gen, may.audit_points);
    else showPrivacy(info, null, noAudit(may.admin === false, "no ID.audit.json next to the map"));
    if (gen === state.mapGen) setStatus(`map ${id} open`);
  } catch (e) {
    if (gen === state.mapGen) setError(`Map ${id}: ${e.message}`);
  }
}

// The map's privacy panel: who can see its lines, and what the audit says.
// `missing`: why there is no audit (the server's word: none beside the map,
// or none for this token).
function showPrivacy(info, audit, missing = "") {
  const rows = [["readers see the lines", info.publish_lines ? "yes: the owner published them" : "no: readers get poses only"]];
  const within1 = audit?.density_attack?.recovery?.within_diagonal_percent?.["1"];
  const share = within1 ?? info.audit_recovered_share;
  rows.push(["audit", share === undefined ? (missing || "none shown")
    : `${(100 * share).toFixed(1)} % of the points recovered within 1 % of the scene`]);
  describe($("privacy-facts"), rows);
  $("privacy").hidden = false;
}

const NO_LINES_NOTE = "The owner has not published this map's lines: this token gets poses only.";

// Why the privacy panel shows no audit: a reader's token, or none beside the map (`why`).
function noAudit(reader, why) {
  return reader ? "not shown to this token (the map's owner sees it)"
    : `none published with this map (${why}: \`linecloud audit --out DIR\`, then its report.json as ID.audit.json)`;
}

async function loadAudit(id, gen, withPoints = true) {
  let report;
  try {
    report = await api(`/v1/maps/${encodeURIComponent(id)}/audit`);
  } catch (e) {
    if (gen !== state.mapGen) return;
    if (e.status !== 404) setError(`Audit: ${e.message}`);
    else showPrivacy(state.info, null, noAudit(e.serverMessage === "no audit for this token", e.serverMessage));
    return;
  }
  if (gen !== state.mapGen) return;
  const rec = report.density_attack?.recovery;
  if (!rec) return;
  showPrivacy(state.info, report);
  const table = $("audit-shares");
  table.replaceChildren();
  const head = table.insertRow();
  for (const t of ["within (of the scene diagonal)", "share of the points"]) {
    const th = document.createElement("th");
    th.textContent = t;
    head.append(th);
  }
  const shares = Object.entries(rec.within_diagonal_percent || {}).sort((a, b) => Number(a[0]) - Number(b[0]));
  for (const [pct, share] of shares) {
    const row = table.insertRow();
    row.insertCell().textContent = `${pct} %`;
    row.insertCell().textContent = `${(100 * share).toFixed(1)} %`;
  }
  $("audit").hidden = false;
  if (withPoints) await loadRecoveredPoints(id, gen);
}

// The points the audit's attack recovered, coloured by their error (the
// audit's colour-blind-safe scale), beside the lines.
async function loadRecoveredPoints(id, gen) {
  let answer;
  try {
    answer = await api(`/v1/maps/${encodeURIComponent(id)}/audit/points`, { binary: true });
  } catch (e) {
    if (e.status === 404) return;
    throw e;
  }
  if (gen !== state.mapGen) return;
  const n = Number(answer.headers.get("X-Linecloud-Points"));
  $("audit-points-count").textContent = `${n.toLocaleString("en")} points recovered by the attack`;
  const view = state.view;
  if (!view) return;
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(answer.bytes, 0, 3 * n), 3));
  geometry.setAttribute("color", new THREE.BufferAttribute(new Uint8Array(answer.bytes, 12 * n, 3 * n), 3, true));
  view.recovered = new THREE.Points(geometry, new THREE.PointsMaterial({ size: 4, sizeAttenuation: false, vertexColors: true, ...OVER_LINES }));
  view.recovered.renderOrder = 1;
  view.recovered.visible = $("show-recovered").checked;
  view.scene.add(view.recovered);
  // The lines dimmed under the points (at 0.6 the scene and the camera were lost in them);
  // the opacity slider says so and gives them back.
  if (view.recovered.visible && view.lines && Number($("opacity").value) > RECOVERED_LINE_OPACITY) {
    $("opacity").value = String(RECOVERED_LINE_OPACITY);
    view.lines.material.opacity = RECOVERED_LINE_OPACITY;
  }
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

function removeFromView(name) {
  const view = state.view;
  if (!view || !view[name]) return;
  view.scene.remove(view[name]);
  view[name].geometry?.dispose();
  view[name].material?.dispose();
  view[name] = null;
  view.dirty = true;
}

function makeView() {
  if (state.view || !webglAvailable()) {
    if (!state.view) $("webgl-missing").hidden = false;
    return state.view;
  }
  const el = $("view");
  // The picture is built over several frames (below): the buffer is kept between them.
  const renderer = new THREE.WebGLRenderer({ antialias: false, powerPreference: "high-performance",
                                             preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.autoClear = false;
  el.append(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1e6);
  const controls = new OrbitControls(camera, renderer.domElement);
  const view = {
    renderer, scene, camera, controls, lines: null, recovered: null, frustum: null,
    frame: null, up: new THREE.Vector3(0, -1, 0), dirty: true,
    // Level of detail: each animation frame draws `chunk` more lines onto the
    // picture, `chunk` tuned so that a frame takes ~25 ms. While the view moves
    // every frame starts a new picture: its first chunk, a uniform subset (the
    // server's order is random). At rest the picture completes chunk by chunk.
    chunk: 2000, drawn: 0,
  };
  // The canvas follows its box (window, phone rotation, layout changes).
  const resize = () => {
    const w = Math.max(1, el.clientWidth), h = Math.max(1, el.clientHeight);
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    view.dirty = true;
  };
  new ResizeObserver(resize).observe(el);
  resize();
  el.addEventListener("keydown", (ev) => {
    const step = { ArrowLeft: [0.05, 0], ArrowRight: [-0.05, 0], ArrowUp: [0, 0.05], ArrowDown: [0, -0.05] }[ev.key];
    if (!step) return;
    const offset = camera.position.clone().sub(controls.target);
    const q = new THREE.Quaternion().setFromUnitVectors(camera.up, new THREE.Vector3(0, 1, 0));
    const s = new THREE.Spherical().setFromVector3(offset.applyQuaternion(q));
    s.theta += step[0];
    s.phi = Math.min(Math.PI - 0.01, Math.max(0.01, s.phi + step[1]));
    camera.position.copy(controls.target).add(new THREE.Vector3().setFromSpherical(s).applyQuaternion(q.invert()));
    camera.lookAt(controls.target);
    view.dirty = true;
    ev.preventDefault();
  });
  controls.addEventListener("change", () => { view.dirty = true; });
  const loop = () => {
    controls.update();
    drawChunk(view);
    requestAnimationFrame(loop);
  };
  requestAnimationFrame(loop);
  state.view = view;
  return view;
}

// One frame's drawing: a new picture when the view changed, else the next
// chunk of lines onto the current one; nothing when it is complete (an idle
// console costs no CPU). Each chunk is timed (a one-pixel read waits for it).
function drawChunk(view) {
  const total = view.lines ? view.lines.userData.segments : 0;
  if (view.dirty) {
    view.dirty = false;
    view.drawn = 0;
    view.renderer.clear();
  } else if (view.drawn >= total) {
    return false;
  }
  const count = Math.min(view.chunk, total - view.drawn);
  if (view.lines) view.lines.geometry.setDrawRange(2 * view.drawn, 2 * count);
  // The points and the camera (drawn over the lines) in the first chunk and the last only.
  const between = view.drawn > 0 && view.drawn + count < total;
  const others = [view.recovered, view.frustum].filter((o) => o);
  const shown = others.map((o) => o.visible);
  if (between) for (const o of others) o.visible = false;
  const t0 = performance.now();
  view.renderer.render(view.scene, view.camera);
  others.forEach((o, i) => { o.visible = shown[i]; });
  const gl = view.renderer.getContext();
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
  const ms = performance.now() - t0;
  if (count === view.chunk) {  // a full chunk: tune the next one towards 25 ms
    view.chunk = Math.round(Math.min(1e6, Math.max(200, view.chunk * Math.min(4, Math.sqrt(25 / Math.max(ms, 0.5))))));
  }
  view.drawn = total ? view.drawn + count : 1;
  return true;
}

// The complete picture now (tests, pixel statistics).
function drawAll(view) {
  view.dirty = true;
  while (drawChunk(view)) { /* chunk after chunk */ }
}

// The scene's box from the 5th to the 95th percentile of the points (the
// segments' end points, the recovered points) on each axis: a few far lines
// do not shrink the scene to a dot.
function robustFrame(positions) {
  const n = positions.length / 3;
  const stride = Math.max(1, Math.floor(n / 20000));
  const axes = [[], [], []];
  for (let i = 0; i < n; i += stride) for (let k = 0; k < 3; ++k) axes[k].push(positions[3 * i + k]);
  const lo = [], hi = [];
  for (const a of axes) {
    a.sort((x, y) => x - y);
    lo.push(a[Math.floor(0.05 * (a.length - 1))] ?? 0);
    hi.push(a[Math.ceil(0.95 * (a.length - 1))] ?? 0);
  }
  const min = new THREE.Vector3(...lo), max = new THREE.Vector3(...hi);
  const center = min.clone().add(max).multiplyScalar(0.5);
  return { center, radius: Math.max(1e-6, 0.5 * max.distanceTo(min)) };
}

// A horizontal direction to look along (perpendicular to up).
function horizontal(up) {
  const candidate = Math.abs(up.z) < 0.9 ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(1, 0, 0);
  return candidate.sub(up.clone().multiplyScalar(candidate.dot(up))).normalize();
}

function placeCamera(view, position, target, up) {
  view.camera.up.copy(up);
  view.camera.position.copy(position);
  view.controls.target.copy(target);
  view.camera.lookAt(target);
  const r = view.frame?.radius ?? 1;
  view.camera.near = r / 1000;
  view.camera.far = r * 200;
  view.camera.updateProjectionMatrix();
  view.controls.update();
  view.dirty = true;
}

// Reset: the scene framed from the side, gravity up (when the map knows it).
function resetView(view = state.view) {
  if (!view?.frame) return;
  const { center, radius } = view.frame;
  const back = horizontal(view.up).multiplyScalar(-2.4 * radius);
  placeCamera(view, center.clone().add(back).addScaledVector(view.up, 0.6 * radius), center, view.up);
}

// What Fit frames: the scene the owner's audit recovered (when shown) and the
// photos localized on this map; the lines only when there is neither (a
// line runs far beyond the point it was lifted from).
function sceneFrame(view) {
  const points = [];
  const recovered = view.recovered?.visible ? view.recovered.geometry.getAttribute("position").array : [];
  for (const v of recovered) points.push(v);
  for (const e of state.history) if (e.map === state.map) points.push(...e.center);
  if (recovered.length === 0 && points.length < 6) return view.frame;
  const frame = robustFrame(points);
  frame.radius = Math.max(frame.radius, 0.05 * view.frame.radius);
  return frame;
}

// Up by the map's gravity (it points down), or null.
function gravityUp() {
  const g = state.info?.gravity;
  return g ? new THREE.Vector3(...g).normalize().negate() : null;
}

// Up in the map: its gravity; without one, the photos localized on it (the
// mean of their cameras' up, -y) when they agree; else unknown.
function sceneUp() {
  const gravity = gravityUp();
  if (gravity) return gravity;
  const sum = new THREE.Vector3();
  let n = 0;
  for (const e of state.history) {
    if (e.map !== state.map) continue;
    sum.add(new THREE.Vector3(0, -1, 0).applyMatrix4(quatToMatrix(e.q).transpose()));
    n += 1;
  }
  return n && sum.length() > 0.5 * n ? sum.normalize() : null;
}

// Top view: offered once up is known (a map without gravity: after a photo).
function updateTopButton() {
  const known = !!sceneUp();
  $("top").disabled = !known;
  $("top").title = known ? "" : "Top view needs to know which way is up: the map has no gravity; localize a photo first";
}

// Fit: the scene framed along the current viewing direction.
function fitView(view = state.view) {
  if (!view?.frame) return;
  const { center, radius } = sceneFrame(view);
  const dir = view.camera.position.clone().sub(view.controls.target).normalize();
  const distance = radius / Math.sin(THREE.MathUtils.degToRad(view.camera.fov / 2));
  placeCamera(view, center.clone().addScaledVector(dir, distance), center, view.camera.up.clone());
}

// Top view: looking down (the audit's view of a floor plan) on the scene Fit frames.
function topView(view = state.view) {
  const up = sceneUp();
  if (!view?.frame || !up) return;
  const { center, radius } = sceneFrame(view);
  placeCamera(view, center.clone().addScaledVector(up, 3 * radius), center, horizontal(up));
}

// Go to camera: just behind and above the localized photo's camera, looking
// where it looks: its frustum in front and the scene it saw beyond (from the
// camera centre itself the nearest lines filled the view).
function goToCamera(view = state.view) {
  const pose = state.pose;
  if (!view || !pose) return;
  const worldFromCam = quatToMatrix(pose.q).transpose();
  const axis = new THREE.Vector3(0, 0, 1).applyMatrix4(worldFromCam);
  const up = new THREE.Vector3(0, -1, 0).applyMatrix4(worldFromCam);
  const centre = new THREE.Vector3(...pose.center);
  const r = view.frame?.radius ?? 1;
  const eye = centre.clone().addScaledVector(axis, -0.3 * r).addScaledVector(up, 0.1 * r);
  placeCamera(view, eye, centre.clone().addScaledVector(axis, 0.5 * r), up);
}

// Frames per second while the view turns, each frame drawn and waited for (a
// one-pixel read): the drawing's own cost, not the browser's frame scheduling
// (headless chromium's emulated vsync stalls software rendering).
function measureFrames(view, ms) {
  const axis = view.camera.up.clone();
  let frames = 0;
  const t0 = performance.now();
  while (performance.now() - t0 < ms || frames < 3) {
    view.camera.position.sub(view.controls.target).applyAxisAngle(axis, 0.02).add(view.controls.target);
    view.camera.lookAt(view.controls.target);
    view.dirty = true;
    drawChunk(view);
    frames += 1;
  }
  return { frames, ms: performance.now() - t0 };
}

async function loadSegments(gen) {
  const limit = Math.max(100, Number($("limit").value) || 20000);
  let answer;
  try {
    answer = await api(`/v1/maps/${encodeURIComponent(state.map)}/segments?limit=${limit}`, { binary: true });
  } catch (e) {
    if (e.status !== 403) throw e;
    if (gen === state.mapGen) $("view-note").textContent = NO_LINES_NOTE;
    return;
  }
  if (gen !== state.mapGen) return;
  const { bytes, headers } = answer;
  const total = Number(headers.get("X-Linecloud-Lines"));
  const shown = Number(headers.get("X-Linecloud-Segments"));
  $("view-count").textContent = `${shown.toLocaleString("en")} of ${total.toLocaleString("en")} lines shown` +
                                (shown < total ? " (a fixed random subset)" : "");
  const view = makeView();
  if (!view) return;
  removeFromView("lines");
  const positions = new Float32Array(bytes);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(positions, 3));
  view.lines = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({
    color: colour("lines"), transparent: true, opacity: Number($("opacity").value), depthWrite: false }));
  view.lines.userData.segments = shown;
  view.lines.visible = $("show-lines").checked;
  view.scene.add(view.lines);
  view.frame = robustFrame(positions);
  view.up = gravityUp() ?? new THREE.Vector3(0, -1, 0);
  resetView(view);
  $("view-note").textContent = shown > 20000
    ? "Many lines: while the view moves a uniform subset is drawn, the rest is added once it rests." : "";
}

// The test's window into the view: what is in the scene and how it is drawn.
window.linecloudScene = () => {
  const v = state.view;
  if (!v) return null;
  const count = (o) => (o ? o.geometry.getAttribute("position").count : 0);
  return {
    lines: v.lines ? v.lines.userData.segments : 0, visible: !!v.lines?.visible,
    opacity: v.lines?.material.opacity ?? null, chunk: v.chunk, drawn: v.drawn,
    recovered: count(v.recovered), frustum: count(v.frustum),
    up: v.camera.up.toArray(), target: v.controls.target.toArray(), position: v.camera.position.toArray(),
    radius: v.frame?.radius ?? null, canvas: [v.renderer.domElement.width, v.renderer.domElement.height],
  };
};

// Pixel statistics of the view, drawn and read in one go (the browser test
// checks that the canvas is not blank): share of lit pixels, mean, std.
window.linecloudViewPixels = () => {
  const view = state.view;
  if (!view) return null;
  drawAll(view);
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

// Frames per second while the view turns (as a user dragging it sees them),
// and the time the complete picture takes at rest. The browser test reads them.
window.linecloudFps = async (ms = 2000) => {
  const view = state.view;
  if (!view) return 0;
  let frames = 0, spent = 0;
  while (spent < ms) {  // in slices, so that the page stays responsive
    const r = measureFrames(view, 100);
    frames += r.frames;
    spent += r.ms;
    await new Promise((resolve) => setTimeout(resolve, 0));
  }
  return frames / (spent / 1000);
};
window.linecloudFullPictureMs = () => {
  const view = state.view;
  if (!view) return null;
  const t0 = performance.now();
  drawAll(view);
  return performance.now() - t0;
};

// ---- localizing a photo ---------------------------------------------------

function quatToMatrix([w, x, y, z]) {
  return new THREE.Matrix4().makeRotationFromQuaternion(new THREE.Quaternion(x, y, z, w));
}

// q and -q are one rotation; shown and exported with w >= 0.
function canonicalQuaternion(q) {
  return q[0] < 0 ? q.map((v) => -v) : q.slice();
}

function parseCamera(text) {
  const [model, w, h, ...p] = text.trim().split(/\s+/);
  const simple = model.startsWith("SIMPLE") || model.startsWith("RADIAL");
  const fx = Number(p[0]), fy = simple ? fx : Number(p[1]);
  const cx = Number(simple ? p[1] : p[2]), cy = Number(simple ? p[2] : p[3]);
  return { model, width: Number(w), height: Number(h), fx, fy, cx, cy };
}

// The camera's frustum (cam_from_world q, t) in the map frame.
function showFrustum(pose, cam) {
  const view = state.view;
  if (!view) return;
  removeFromView("frustum");
  const worldFromCam = quatToMatrix(pose.q).transpose();
  const centre = new THREE.Vector3(...pose.center);
  const depth = 0.08 * (view.frame?.radius ?? 1);
  const corners = [[0, 0], [cam.width, 0], [cam.width, cam.height], [0, cam.height]].map(([u, v]) =>
    new THREE.Vector3((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1).multiplyScalar(depth).applyMatrix4(worldFromCam).add(centre));
  const points = [];
  for (let i = 0; i < 4; ++i) points.push(centre, corners[i], corners[i], corners[(i + 1) % 4]);
  view.frustum = new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(points),
                                        new THREE.LineBasicMaterial({ color: colour("near"), ...OVER_LINES }));
  view.frustum.renderOrder = 2;
  view.scene.add(view.frustum);
  view.dirty = true;
}

// The EXIF orientation of a JPEG (1 when it has none or is a PNG).
async function exifOrientation(file) {
  const b = new DataView(await file.slice(0, 128 * 1024).arrayBuffer());
  if (b.byteLength < 4 || b.getUint16(0) !== 0xffd8) return 1;
  for (let p = 2; p + 4 <= b.byteLength;) {
    const marker = b.getUint16(p), length = b.getUint16(p + 2);
    if ((marker & 0xff00) !== 0xff00 || marker === 0xffda) break;  // the image data: no EXIF before it
    if (marker === 0xffe1 && p + 18 <= b.byteLength && b.getUint32(p + 4) === 0x45786966) {  // "Exif"
      const tiff = p + 10, little = b.getUint16(tiff) === 0x4949;
      const ifd = tiff + b.getUint32(tiff + 4, little);
      if (ifd + 2 > b.byteLength) break;
      for (let i = 0, n = b.getUint16(ifd, little); i < n && ifd + 14 + 12 * i <= b.byteLength; ++i) {
        const e = ifd + 2 + 12 * i;
        if (b.getUint16(e, little) === 0x0112) {
          const v = b.getUint16(e + 8, little);
          return v >= 1 && v <= 8 ? v : 1;
        }
      }
      break;
    }
    p += 2 + length;
  }
  return 1;
}

// The transform from displayed to stored pixels for each EXIF orientation
// (canvas setTransform's a, b, c, d, e, f; W, H: the stored size).
const FROM_DISPLAYED = {
  1: () => [1, 0, 0, 1, 0, 0], 2: (W) => [-1, 0, 0, 1, W, 0], 3: (W, H) => [-1, 0, 0, -1, W, H],
  4: (W, H) => [1, 0, 0, -1, 0, H], 5: () => [0, 1, 1, 0, 0, 0], 6: (W, H) => [0, -1, 1, 0, 0, H],
  7: (W, H) => [0, -1, -1, 0, W, H], 8: (W) => [0, 1, -1, 0, W, 0],
};

// The photo as the server read it: turned by its EXIF orientation, unless the
// camera is the size of the stored pixels (then the server used those). The
// browser decodes it turned; the stored pixels are drawn by turning it back.
async function photoAsLocalized(file, cam) {
  const shown = await createImageBitmap(file);
  const o = await exifOrientation(file);
  const turned = o >= 5;
  const width = turned ? shown.height : shown.width, height = turned ? shown.width : shown.height;
  const stored = o !== 1 && cam.width === width && cam.height === height;
  return { shown, orientation: stored ? "stored" : "displayed", exif: o,
           width: stored ? width : shown.width, height: stored ? height : shown.height };
}

// The photo with what the CLI's --overlay draws (for the map's owner): inliers,
// outliers and the inliers' map lines where the pose puts them.
async function drawOverlay(file, r, cam, gen) {
  const photo = await photoAsLocalized(file, cam);
  if (gen !== state.requestGen) return;  // another request, map or token meanwhile
  const { orientation } = photo;
  const canvas = $("overlay");
  const scale = Math.min(1, 640 / photo.width);
  canvas.width = Math.round(photo.width * scale);
  canvas.height = Math.round(photo.height * scale);
  const ctx = canvas.getContext("2d");
  ctx.filter = "grayscale(1) brightness(0.75)";
  const [a, b, c, d, e, f] = orientation === "stored" ? FROM_DISPLAYED[photo.exif](photo.width, photo.height) : FROM_DISPLAYED[1]();
  ctx.setTransform(scale * a, scale * b, scale * c, scale * d, scale * e, scale * f);
  ctx.drawImage(photo.shown, 0, 0);
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.filter = "none";
  const at = (x, y) => [(x - 0.5) * scale, (y - 0.5) * scale];  // COLMAP's pixel centres
  ctx.lineWidth = 1.5;
  ctx.strokeStyle = colour("near");
  let segments = 0;
  for (const s of r.inlier_segments || []) {
    if (!s) continue;
    ctx.beginPath();
    ctx.moveTo(...at(s[0], s[1]));
    ctx.lineTo(...at(s[2], s[3]));
    ctx.stroke();
    segments += 1;
  }
  const circles = (points, name) => {
    ctx.strokeStyle = colour(name);
    for (const [x, y] of points || []) {
      ctx.beginPath();
      ctx.arc(...at(x, y), 2.5, 0, 2 * Math.PI);
      ctx.stroke();
    }
  };
  circles(r.outlier_keypoints, "far");
  circles(r.inlier_keypoints, "exact");
  const inliers = (r.inlier_keypoints || []).length, outliers = (r.outlier_keypoints || []).length;
  Object.assign(canvas.dataset, { inliers, outliers, segments, orientation, exif: photo.exif });
  canvas.setAttribute("aria-label", r.inlier_keypoints
    ? `${file.name}: ${inliers} inliers, ${outliers} outliers and ${segments} map lines drawn on the photo`
    : `${file.name}: the photo (the correspondences are shown to the map's owner only)`);
  canvas.hidden = false;
  $("overlay-legend").hidden = !r.inlier_keypoints;
}

function recentCameras() {
  try { return JSON.parse(localStorage.getItem("linecloud-cameras") || "[]"); } catch { return []; }
}

function rememberCamera(text, good) {
  const recent = recentCameras().filter((c) => c !== text);
  if (good) recent.unshift(text);
  localStorage.setItem("linecloud-cameras", JSON.stringify(recent.slice(0, 8)));
  fillRecentCameras();
}

function fillRecentCameras() {
  const list = $("recent-cameras");
  list.replaceChildren();
  for (const c of recentCameras()) {
    const o = document.createElement("option");
    o.value = c;
    list.append(o);
  }
}

// Checked before the upload: a JPEG or PNG (by its first bytes), not larger
// than the server takes.
async function checkPhoto(file) {
  if (!file) return "choose a photo";
  if (file.size > MAX_PHOTO_BYTES) {
    return `${file.name} is ${(file.size / 2 ** 20).toFixed(1)} MB; the server takes photos up to ${MAX_PHOTO_BYTES / 2 ** 20} MB`;
  }
  const head = new Uint8Array(await file.slice(0, 8).arrayBuffer());
  const jpeg = head[0] === 0xff && head[1] === 0xd8 && head[2] === 0xff;
  const png = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a].every((b, i) => head[i] === b);
  if (!jpeg && !png) return `${file.name} is not a JPEG or PNG photo`;
  return null;
}

function setBusy(busy) {
  state.busy = busy;
  $("localize-button").disabled = busy;
  $("localize").setAttribute("aria-busy", String(busy));
}

// One request at a time: busy from the first click (the checks included) to the answer.
async function localize(file) {
  if (state.busy) return;
  setBusy(true);
  try {
    await localizeNow(file);
  } finally {
    setBusy(false);
  }
}

async function localizeNow(file) {
  if (!state.map) return setError("open a map first");
  clearRequest();  // a new request: the last one's pose and photo go, whatever follows
  const gen = state.requestGen, mapGen = state.mapGen, map = state.map;
  const problem = await checkPhoto(file);
  if (gen !== state.requestGen) return;
  if (problem) return setPhotoError(problem);
  const cameraText = $("camera").value.trim();
  // The photo stays chosen: give the camera, then Localize.
  if (!cameraText) return setPhotoError(`give the camera of ${file.name}, then Localize`);
  const form = new FormData();
  form.append("image", file, file.name);
  form.append("camera", cameraText);
  setStatus(`localizing ${file.name} ...`);
  try {
    const r = await api(`/v1/maps/${encodeURIComponent(map)}/localize`, { method: "POST", body: form });
    if (gen !== state.requestGen || mapGen !== state.mapGen) return;
    if (!r.success) {
      describe($("pose"), [["success", "no pose", false], ["reason", r.reason]]);
      setPhotoError(`no pose for ${file.name}: ${r.reason}`);
      return;
    }
    rememberCamera(cameraText, true);
    const q = canonicalQuaternion(r.q);
    const f = (v) => v.map((x) => x.toFixed(6)).join(", ");
    const t = r.times_ms;
    describe($("pose"), [
      ["success", "pose found", true],
      ["q", f(q), q],
      ["t", f(r.t), r.t],
      ["center", f(r.center), r.center],
      ["inliers", `${r.num_inliers} of ${r.num_matches} matches (${(100 * r.inlier_ratio).toFixed(1)} %)`, r.num_inliers],
      ["uncertainty", `${r.uncertainty.rotation_deg.toFixed(4)}°, ${r.uncertainty.position.toFixed(4)} map units`],
      ["times", `decode ${t.decode.toFixed(0)} · extract ${t.extract.toFixed(0)} · match ${t.match.toFixed(0)} · RANSAC ${t.ransac.toFixed(1)} · total ${t.total.toFixed(0)} ms`],
    ]);
    const cam = parseCamera(cameraText);
    state.pose = { q, t: r.t, center: r.center };
    $("goto").disabled = !state.view;
    showFrustum(state.pose, cam);
    addToHistory({ map, name: file.name, camera: cameraText, q, t: r.t, center: r.center,
                   num_inliers: r.num_inliers, num_matches: r.num_matches });
    await drawOverlay(file, r, cam, gen);
    if (gen === state.requestGen) setStatus(`${file.name}: localized`);
  } catch (e) {
    if (gen !== state.requestGen) return;
    if (e.status === 400 && /camera/i.test(e.message)) rememberCamera(cameraText, false);
    setPhotoError(`Localize ${file.name}: ${e.message}`);
  }
}

// ---- the session's queries, with their poses to take away ----------------

function addToHistory(entry) {
  state.history.unshift({ ...entry, when: new Date().toISOString(), id: state.history.length + 1 });
  renderHistory();
  updateTopButton();
}

// One line of COLMAP's images.txt: IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME.
function colmapImageLine(e) {
  return [e.id, ...e.q, ...e.t, 1, e.name.replace(/\s/g, "_")].join(" ");
}

function download(name, text, type) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([text], { type }));
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

function renderHistory() {
  const list = $("history");
  list.replaceChildren();
  for (const e of state.history) {
    const li = document.createElement("li");
    const json = JSON.stringify({ map: e.map, image: e.name, camera: e.camera,
                                  cam_from_world: { rotation: e.q, translation: e.t }, center: e.center,
                                  num_inliers: e.num_inliers, num_matches: e.num_matches, time: e.when }, null, 2);
    li.dataset.json = json;
    li.dataset.colmap = colmapImageLine(e);
    li.append(`${e.name} on ${e.map}: ${e.num_inliers} inliers, centre ${e.center.map((v) => v.toFixed(3)).join(", ")} `);
    const stem = e.name.replace(/\.[^.]*$/, "");
    for (const [label, name, text, type] of [["JSON", `${stem}.pose.json`, json, "application/json"],
                                             ["images.txt", `${stem}.images.txt`, `${li.dataset.colmap}\n\n`, "text/plain"]]) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = label;
      b.setAttribute("aria-label", `Download the pose of ${e.name} as ${label}`);
      b.addEventListener("click", () => download(name, text, type));
      li.append(b);
    }
    list.append(li);
  }
}

// ---- wiring ---------------------------------------------------------------

$("login").addEventListener("submit", (ev) => {
  ev.preventDefault();
  signIn($("token").value.trim());
});
$("logout-button").addEventListener("click", signOut);
// The photo to localize: the one chosen or dropped last (a dropped one is
// kept while the camera is typed).
$("photo").addEventListener("change", () => choosePhoto($("photo").files[0] || null, false));
function choosePhoto(file, dropped) {
  state.photo = file;
  if (dropped) $("photo").value = "";  // not the previous file's name beside the dropped one
  $("drop").textContent = file && dropped ? `photo: ${file.name}` : "or drop a photo here";
}
$("localize").addEventListener("submit", (ev) => {
  ev.preventDefault();
  localize(state.photo);
});
// More or fewer lines of the same map: its pose, audit and photo stay.
$("limit").addEventListener("change", () => {
  const gen = state.mapGen;
  if (state.map && state.info?.for_this_token?.segments !== false) {
    loadSegments(gen).catch((e) => gen === state.mapGen && setError(`Lines: ${e.message}`));
  }
});
$("show-lines").addEventListener("change", () => {
  if (state.view?.lines) {
    state.view.lines.visible = $("show-lines").checked;
    state.view.dirty = true;
  }
});
$("opacity").addEventListener("input", () => {
  if (state.view?.lines) {
    state.view.lines.material.opacity = Number($("opacity").value);
    state.view.dirty = true;
  }
});
$("fit").addEventListener("click", () => fitView());
$("reset").addEventListener("click", () => resetView());
$("top").addEventListener("click", () => topView());
$("goto").addEventListener("click", () => goToCamera());
const drop = $("drop");
drop.addEventListener("dragover", (ev) => { ev.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (ev) => {
  ev.preventDefault();
  drop.classList.remove("over");
  choosePhoto(ev.dataTransfer.files[0] || null, true);
  localize(state.photo);
});
drop.addEventListener("click", () => $("photo").click());
drop.addEventListener("keydown", (ev) => {
  if (ev.key === "Enter" || ev.key === " ") {
    ev.preventDefault();
    $("photo").click();
  }
});
$("show-recovered").addEventListener("change", () => {
  if (state.view?.recovered) {
    state.view.recovered.visible = $("show-recovered").checked;
    state.view.dirty = true;
  }
});
fillRecentCameras();
// On a phone the map's details start folded: the photo panel comes next.
if (window.matchMedia("(max-width: 700px)").matches) $("map-details").open = false;
$("token").value = state.token;
if (!webglAvailable()) $("webgl-missing").hidden = false;
