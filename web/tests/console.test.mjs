// End-to-end test of the console: Debian's chromium, headless, driven by
// playwright-core against `linecloud serve` on 127.0.0.1 (a random port) with
// fountain-P11's map (group g00, built without 0000.jpg) and a 100 000-line
// map. It uses the console as its people do — owner and reader, desktop and a
// 390 px phone, keyboard only, several maps, bad files — and checks that what
// is shown is what is open. Screenshots go to build/web-test/ for people to look at.
//
//   node web/tests/console.test.mjs      (after scripts/build_web.sh)
import { chromium } from "playwright-core";
import { spawn, execFileSync } from "node:child_process";
import { existsSync, mkdirSync, mkdtempSync, readFileSync, writeFileSync, copyFileSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";
import assert from "node:assert/strict";

const repo = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const binary = process.env.LINECLOUD_BINARY || `${repo}/build/linecloud`;
const work = process.env.LINECLOUD_FOUNTAIN_WORK || `${repo}/build/eval/fountain-P11`;
// The data folder by the rule of docs/data.md.
const beside = path.resolve(repo, "../shared/data");
const data = process.env.LINECLOUD_DATA || (existsSync(beside) ? beside : `${repo}/data`);
const photo = `${data}/strecha/fountain-P11/images/0000.jpg`;
const camera = "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155";
// The same camera for the photo turned a quarter clockwise (EXIF orientation 6, as displayed).
const turnedCamera = "PINHOLE 1024 1536 1382.08 1379.74 520.845 760.095";
const shots = `${repo}/build/web-test`;
const chromiumPath = process.env.CHROMIUM || "/usr/bin/chromium";

for (const [what, p] of [["eval prepare work of fountain-P11 (LINECLOUD_FOUNTAIN_WORK)", `${work}/prepared.json`],
                         ["fountain-P11 photo (scripts/get_data.sh)", photo], ["linecloud binary", binary],
                         ["chromium (apt-get install chromium)", chromiumPath],
                         ["console (bash scripts/build_web.sh)", `${repo}/build/web/index.html`]]) {
  if (!existsSync(p)) {
    // Under the test command (LINECLOUD_REQUIRE_ALL=1) a part that cannot run is a failure.
    const required = process.env.LINECLOUD_REQUIRE_ALL === "1";
    console.log(`console test ${required ? "FAILED" : "SKIPPED"}: no ${what} at ${p}`);
    process.exit(required ? 1 : 0);
  }
}
mkdirSync(shots, { recursive: true });
const tmp = mkdtempSync(path.join(tmpdir(), "linecloud-web-"));
const env = { ...process.env, LINECLOUD_KEY_STORE: `${tmp}/keys` };
const run = (args) => execFileSync(binary, args, { env, stdio: ["ignore", "pipe", "pipe"] }).toString();

// Maps: fountain (with the owner's audit) and 100 000 random lines.
mkdirSync(`${tmp}/maps`);
// Under a fixed, public test key: the same lines, poses and audit on every run.
writeFileSync(`${tmp}/fixed.key`, `# fixed public test key\ndirections sphere\n${"5a".repeat(32)}\n`, { mode: 0o600 });
run(["lift", "--model", `${work}/groups/g00/map`, "--database", `${work}/colmap/database.db`,
     "--key-file", `${tmp}/fixed.key`, "--out", `${tmp}/maps/fountain.lcm`, "--quiet"]);
run(["audit", "--map", `${tmp}/maps/fountain.lcm`, "--model", `${work}/groups/g00/map`,
     "--out", `${tmp}/audit`, "--quiet"]);
copyFileSync(`${tmp}/audit/report.json`, `${tmp}/maps/fountain.audit.json`);
copyFileSync(`${tmp}/audit/recovered.ply`, `${tmp}/maps/fountain.audit.ply`);
writeFileSync(`${tmp}/maps/fountain.json`, JSON.stringify({ geo_anchor: { lat: 46.5, lon: 6.6, h: 400,
  enu_from_map: { q: [1, 0, 0, 0], t: [0, 0, 0], scale: 1 } } }));
execFileSync("/usr/bin/python3", ["-c", `
import numpy as np, linecloud as lc
rng = np.random.default_rng(1)
x = rng.uniform(-10, 10, (100000, 3)); v = rng.normal(size=(100000, 3))
v /= np.linalg.norm(v, axis=1, keepdims=True)
lc.LineCloud(np.hstack([v, np.cross(x, v)]), np.arange(100000)).write("${tmp}/maps/big.lcm")`],
             { env: { ...env, PYTHONPATH: `${repo}/build/python` } });
const owner = "console-test-owner-token", reader = "console-test-reader-token", limited = "console-test-limited-token";
const hash = (t) => execFileSync(binary, ["token-hash"], { input: t }).toString().trim().split(/\s+/).pop();
writeFileSync(`${tmp}/tokens.json`, JSON.stringify({ tokens: [
  { id: "owner", sha256: hash(owner), maps: ["*"], requests_per_minute: 6000, admin: true },
  { id: "reader", sha256: hash(reader), maps: ["fountain"], requests_per_minute: 6000, admin: false },
  { id: "limited", sha256: hash(limited), maps: ["fountain"], requests_per_minute: 1, admin: false },
] }));

// fountain's 0000.jpg with an EXIF orientation of 6 (turned a quarter clockwise when displayed):
// an APP1 segment after the start-of-image marker, the pixels untouched.
function withExifOrientation(jpeg, orientation) {
  const tiff = Buffer.from([0x4d, 0x4d, 0x00, 0x2a, 0, 0, 0, 8, 0, 1, 0x01, 0x12, 0, 3, 0, 0, 0, 1,
                            0, orientation, 0, 0, 0, 0, 0, 0]);
  const payload = Buffer.concat([Buffer.from("Exif\0\0", "binary"), tiff]);
  const length = Buffer.alloc(2);
  length.writeUInt16BE(payload.length + 2);
  return Buffer.concat([jpeg.subarray(0, 2), Buffer.from([0xff, 0xe1]), length, payload, jpeg.subarray(2)]);
}
const turnedPhoto = `${tmp}/0000-exif6.jpg`;
writeFileSync(turnedPhoto, withExifOrientation(readFileSync(photo), 6));
writeFileSync(`${tmp}/not-a-photo.jpg`, "this is text, not a JPEG\n");

const server = spawn(binary, ["serve", "--maps", `${tmp}/maps`, "--listen", "127.0.0.1:0",
                              "--tokens", `${tmp}/tokens.json`, "--threads", "2"], { env });
let serverLog = "";
const base = await new Promise((resolve, reject) => {
  server.stderr.on("data", (d) => {
    serverLog += d;
    const m = /listening on (http:\/\/127\.0\.0\.1:\d+)/.exec(serverLog);
    if (m) resolve(m[1]);
  });
  server.on("exit", (code) => reject(new Error(`serve exited ${code}: ${serverLog}`)));
  setTimeout(() => reject(new Error(`serve did not start: ${serverLog}`)), 60000);
});

async function apiLocalize(file, cam, token) {
  const form = new FormData();
  form.append("image", new Blob([readFileSync(file)], { type: "image/jpeg" }), path.basename(file));
  form.append("camera", cam);
  const res = await fetch(`${base}/v1/maps/fountain/localize`, { method: "POST", body: form, headers: { Authorization: `Bearer ${token}` } });
  return res.json();
}
const canonical = (q) => (q[0] < 0 ? q.map((v) => -v) : q);
const near = (a, b, tol, what) => {
  assert.equal(a.length, b.length, what);
  for (let i = 0; i < a.length; ++i) assert.ok(Math.abs(a[i] - b[i]) <= tol, `${what}[${i}]: ${a[i]} vs ${b[i]}`);
};

// ---- page helpers ----------------------------------------------------------
const text = (page, sel) => page.textContent(sel);
async function signIn(page, token) {
  await page.fill("#token", token);
  await page.click("#login-button");
  await page.waitForFunction(() => document.querySelector("#maps button") || document.querySelector("#error").textContent);
}
async function openMap(page, id) {
  await page.click(`#maps button[data-map="${id}"]`);
  await page.waitForFunction((m) => document.querySelector("#status").textContent === `map ${m} open` ||
                                    document.querySelector("#error").textContent, id);
}
async function localizeOnPage(page, file, cam) {
  await page.setInputFiles("#photo", file);
  await page.fill("#camera", cam);
  await page.click("#localize-button");
  await page.waitForFunction(() => document.querySelector("#localize").getAttribute("aria-busy") === "false" &&
                                   (document.querySelector("#pose-q") || document.querySelector("#error").textContent),
                             null, { timeout: 60000 });
}
const scene = (page) => page.evaluate(() => window.linecloudScene());
// Request-level state the page must have cleared.
async function assertNoRequestState(page, what) {
  assert.equal(await page.$("#pose dd"), null, `${what}: the previous pose is gone`);
  assert.equal(await page.getAttribute("#overlay", "hidden"), "", `${what}: the overlay is hidden`);
  const s = await scene(page);
  if (s) assert.equal(s.frustum, 0, `${what}: the camera is gone from the view`);
  assert.equal(await page.isDisabled("#goto"), true, `${what}: nothing to go to`);
}
async function tabTo(page, selector, max = 60) {
  for (let i = 0; i < max; ++i) {
    await page.keyboard.press("Tab");
    if (await page.evaluate((s) => document.activeElement?.matches(s), selector)) return;
  }
  throw new Error(`Tab never reached ${selector}`);
}

// WCAG contrast of every visible text (and of placeholders, input borders) on its background.
function contrastProblems() {
  const rgb = (s) => { const m = s.match(/[\d.]+/g); return m ? m.slice(0, 4).map(Number) : [0, 0, 0, 0]; };
  const lum = ([r, g, b]) => [r, g, b].map((v) => { v /= 255; return v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4; })
    .reduce((a, v, i) => a + v * [0.2126, 0.7152, 0.0722][i], 0);
  const ratio = (a, b) => { const [x, y] = [lum(a), lum(b)].sort((p, q) => q - p); return (x + 0.05) / (y + 0.05); };
  const background = (el) => {
    for (let e = el; e; e = e.parentElement) {
      const c = rgb(getComputedStyle(e).backgroundColor);
      if (c.length < 4 || c[3] > 0) return c;
    }
    return [255, 255, 255];
  };
  const problems = [];
  for (const el of document.querySelectorAll("body *")) {
    const style = getComputedStyle(el);
    if (style.visibility === "hidden" || el.offsetParent === null && style.position !== "fixed") continue;
    const ownText = [...el.childNodes].some((n) => n.nodeType === 3 && n.textContent.trim());
    if (ownText && ratio(rgb(style.color), background(el)) < 4.5) {
      problems.push(`${el.tagName}#${el.id} text ${style.color} on ${background(el)}: ${ratio(rgb(style.color), background(el)).toFixed(2)}`);
    }
    if (el.matches("input:not([type=checkbox]):not([type=range]), button")) {
      const border = rgb(style.borderTopColor), behind = background(el.parentElement);
      if (ratio(border, behind) < 4.5) problems.push(`${el.tagName}#${el.id} border ${style.borderTopColor}: ${ratio(border, behind).toFixed(2)}`);
    }
    if (el.matches("input[placeholder]")) {
      const ph = rgb(getComputedStyle(el, "::placeholder").color);
      if (ratio(ph, background(el)) < 4.5) problems.push(`${el.id} placeholder: ${ratio(ph, background(el)).toFixed(2)}`);
    }
  }
  return problems;
}

// Every control and every non-text element a person uses has a role and a name.
function unnamedControls() {
  const name = (e) => e.getAttribute("aria-label") || e.labels?.[0]?.textContent.trim() ||
    (e.getAttribute("aria-labelledby") && document.getElementById(e.getAttribute("aria-labelledby"))?.textContent.trim()) ||
    e.textContent.trim();
  const missing = [];
  for (const e of document.querySelectorAll("input, button, select, canvas, [tabindex], [role]")) {
    if (e.closest("[hidden]") || e.type === "hidden" || e.matches("[role=status], [role=alert]")) continue;  // live regions
    if (!name(e)) missing.push(`${e.tagName}#${e.id} has no name`);
    if ((e.tagName === "CANVAS" || e.tagName === "DIV") && e.hasAttribute("tabindex") && !e.getAttribute("role")) {
      missing.push(`${e.tagName}#${e.id} is focusable without a role`);
    }
  }
  for (const id of ["view", "drop", "overlay"]) {
    if (!document.getElementById(id).getAttribute("role")) missing.push(`#${id} has no role`);
  }
  return missing;
}

// Okabe and Ito's scale (the audit's points): colours as people with each kind of colour
// vision see them (Viénot, Brettel and Mollon 1999, in linear RGB) stay apart.
function colourBlindDistances(colours) {
  const lin = (v) => { v /= 255; return v <= 0.04045 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4; };
  const sims = {
    protan: [[0.11238, 0.88762, 0], [0.11238, 0.88762, 0], [0.00401, -0.00401, 1]],
    deutan: [[0.29275, 0.70725, 0], [0.29275, 0.70725, 0], [-0.02234, 0.02234, 1]],
    tritan: [[1, 0.1274, -0.1274], [0, 0.8781, 0.1219], [0, 0.8781, 0.1219]],
  };
  const out = {};
  for (const [name, m] of Object.entries(sims)) {
    const seen = colours.map((c) => m.map((row) => row.reduce((a, k, i) => a + k * lin(c[i]), 0)));
    let min = Infinity;
    for (let i = 0; i < seen.length; ++i) for (let j = i + 1; j < seen.length; ++j) {
      min = Math.min(min, Math.hypot(...seen[i].map((v, k) => v - seen[j][k])));
    }
    out[name] = min;
  }
  return out;
}

const results = {};
const browser = await chromium.launch({
  executablePath: chromiumPath,
  args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"],
});
try {
  const context = await browser.newContext({ viewport: { width: 1600, height: 1000 }, acceptDownloads: true });
  const page = await context.newPage();
  const errors = [];
  page.on("pageerror", (e) => errors.push(e.message));
  let posts = 0;
  page.on("request", (r) => { if (r.method() === "POST") posts += 1; });
  const notFound = [];
  page.on("response", (r) => { if (r.status() === 404) notFound.push(new URL(r.url()).pathname); });
  // The map's lines and audit are asked for only when the token may fetch them (the map's
  // for_this_token): no 403 / 404 in the browser's console for a reader or a map without an audit.
  const refused = [];
  page.on("response", (r) => {
    if ([403, 404].includes(r.status()) && /\/(segments|audit)/.test(r.url())) refused.push(`${r.status()} ${new URL(r.url()).pathname}`);
  });

  // ---- loading: compressed, then revalidated (no bytes again) ----------------
  await page.goto(base + "/");
  const nav = await page.evaluate(() => performance.getEntriesByType("navigation")[0].toJSON());
  results.load_ms = nav.loadEventEnd;
  assert.ok(nav.loadEventEnd > 0 && nav.loadEventEnd < 5000, `page load ${nav.loadEventEnd} ms`);
  const firstLoad = await page.evaluate(() => performance.getEntriesByType("resource")
    .reduce((a, r) => ({ transfer: a.transfer + r.transferSize, decoded: a.decoded + r.decodedBodySize }), { transfer: 0, decoded: 0 }));
  await page.reload();
  const reload = await page.evaluate(() => performance.getEntriesByType("resource")
    .reduce((a, r) => ({ transfer: a.transfer + r.transferSize, decoded: a.decoded + r.decodedBodySize }), { transfer: 0, decoded: 0 }));
  results.bytes = { first_transfer: firstLoad.transfer, first_decoded: firstLoad.decoded, reload_transfer: reload.transfer };
  assert.ok(firstLoad.decoded > 1e6, `three.js and the page: ${firstLoad.decoded} bytes`);
  assert.deepEqual(notFound, [], "nothing the page asks for is missing (a favicon, say)");
  // The camera field's placeholder is an example, not a camera that looks filled in.
  assert.match(await page.getAttribute("#camera", "placeholder"), /^e\.g\. PINHOLE width height fx fy cx cy$/);
  assert.ok(firstLoad.transfer < 0.4 * firstLoad.decoded, `sent compressed: ${firstLoad.transfer} of ${firstLoad.decoded}`);
  assert.ok(reload.transfer < 20000, `a reload revalidates (304s), it does not download again: ${reload.transfer} bytes`);

  // ---- accessibility: names, roles, contrast, the colour scale --------------
  assert.deepEqual(await page.evaluate(unnamedControls), []);
  assert.deepEqual(await page.evaluate(contrastProblems), []);

  // A wrong token: an error, announced, not a blank page.
  await page.fill("#token", "not-a-token");
  await page.press("#token", "Enter");  // the keyboard signs in
  await page.waitForFunction(() => document.querySelector("#error").textContent.includes("Sign-in failed"));
  assert.match(await text(page, "#error"), /does not accept this token \(401\)/);
  assert.doesNotMatch(await text(page, "#error"), /header/i, "a user types a token, not headers");
  assert.equal(await page.getAttribute("#error", "role"), "alert");
  assert.equal(await page.evaluate(() => sessionStorage.getItem("linecloud-token")), null, "a token that failed is not kept");
  await page.screenshot({ path: `${shots}/wrong-token.png` });

  // ---- the owner opens fountain: info, privacy, the view, the audit ----------
  await signIn(page, owner);
  assert.equal(await text(page, "#error"), "");
  await openMap(page, "fountain");
  await page.waitForSelector("#audit:not([hidden])");
  const lines = JSON.parse(readFileSync(`${tmp}/audit/report.json`)).lines;
  await page.waitForFunction((n) => document.querySelector("#audit-points-count").textContent
    .startsWith(`${n.toLocaleString("en")} points recovered`), lines);
  assert.match(await text(page, "#privacy-facts-readers-see-the-lines"), /^no: readers get poses only/);
  assert.equal(await text(page, "#info-geo-anchor"), "46.500000°, 6.600000°, 400.0 m");
  const within1 = JSON.parse(readFileSync(`${tmp}/audit/report.json`)).density_attack.recovery.within_diagonal_percent["1"];
  assert.equal(await text(page, "#privacy-facts-audit"), `${(100 * within1).toFixed(1)} % of the points recovered within 1 % of the scene`);
  assert.deepEqual(await page.evaluate(contrastProblems), []);
  let s = await scene(page);
  assert.equal(s.recovered, lines);
  assert.equal(s.opacity, 0.2, "the lines dimmed under the recovered points");
  assert.equal(await page.inputValue("#opacity"), "0.2", "and the slider says so");
  // Framed on the scene, not on its farthest lines: the target is inside the 5-95 % box.
  assert.ok(s.radius > 0 && s.radius < 100, `radius ${s.radius}`);
  assert.deepEqual(s.up, [0, -1, 0], "no gravity in this map: COLMAP's -y is up");
  // No gravity and no photo yet: which way is up is unknown, no top view offered.
  assert.equal(await page.isDisabled("#top"), true, "top view before anything says which way is up");
  assert.match(await page.getAttribute("#top", "title"), /no gravity; localize a photo first/);
  // The audit's colours: on Okabe and Ito's scale, apart for every colour vision.
  const points = await (await fetch(`${base}/v1/maps/fountain/audit/points`, { headers: { Authorization: `Bearer ${owner}` } })).arrayBuffer();
  const rgb = new Uint8Array(points, 12 * lines, 3 * lines);
  const scale = [[86, 180, 233], [240, 228, 66], [213, 94, 0]];
  const onScale = (c) => [0, 1].some((k) => {
    const [a, b] = [scale[k], scale[k + 1]];
    const t = ((c[0] - a[0]) * (b[0] - a[0]) + (c[1] - a[1]) * (b[1] - a[1]) + (c[2] - a[2]) * (b[2] - a[2])) /
              ((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2);
    return t >= -0.01 && t <= 1.01 && [0, 1, 2].every((i) => Math.abs(a[i] + t * (b[i] - a[i]) - c[i]) <= 2);
  });
  for (let i = 0; i < lines; ++i) assert.ok(onScale([rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]]), `point ${i}: ${rgb.subarray(3 * i, 3 * i + 3)}`);
  // The lines (grey) apart from every colour of the scale (the best-recovered points were sky
  // blue on sky-blue lines).
  const lineColour = await page.evaluate(() => getComputedStyle(document.documentElement).getPropertyValue("--lines").trim());
  const lineRgb = [1, 3, 5].map((i) => parseInt(lineColour.slice(i, i + 2), 16));
  results.colour_blind_min_distance = colourBlindDistances([...scale, lineRgb]);
  for (const [kind, d] of Object.entries(results.colour_blind_min_distance)) assert.ok(d > 0.1, `${kind}: ${d}`);
  await page.waitForTimeout(300);
  const pixels = await page.evaluate(() => window.linecloudViewPixels());
  results.view_pixels = pixels;
  assert.ok(pixels.lit > 0.01 && pixels.lit < 0.99 && pixels.std > 5, `blank view? ${JSON.stringify(pixels)}`);
  await page.screenshot({ path: `${shots}/fountain-map.png` });

  // ---- a held-out photo: the pose the API gives, the overlay the CLI draws ----
  const api = await apiLocalize(photo, camera, owner);
  assert.equal(api.success, true);
  await localizeOnPage(page, photo, camera);
  const shown = { q: JSON.parse(await page.getAttribute("#pose-q", "data-value")),
                  t: JSON.parse(await page.getAttribute("#pose-t", "data-value")) };
  assert.ok(shown.q[0] >= 0, "w >= 0");
  near(shown.q, canonical(api.q), 1e-6, "q");
  near(shown.t, api.t, 1e-6, "t");
  results.pose = { ...shown, num_inliers: api.num_inliers };
  assert.equal(api.inlier_keypoints.length, api.num_inliers);
  assert.equal(api.inlier_keypoints.length + api.outlier_keypoints.length, api.num_matches);
  const overlay = await page.evaluate(() => ({ ...document.querySelector("#overlay").dataset,
    w: document.querySelector("#overlay").width, h: document.querySelector("#overlay").height }));
  assert.equal(Number(overlay.inliers), api.num_inliers);
  assert.equal(Number(overlay.outliers), api.outlier_keypoints.length);
  assert.equal(Number(overlay.segments), api.inlier_segments.filter((x) => x).length);
  assert.ok(Number(overlay.segments) > 0.9 * api.num_inliers);
  assert.equal(overlay.orientation, "displayed");
  assert.deepEqual([overlay.w, overlay.h], [640, 427]);
  s = await scene(page);
  assert.equal(s.frustum, 16, "the camera drawn in the view (4 rays + 4 edges: 16 vertices)");
  // The history: one entry, its COLMAP images.txt line and JSON are the pose shown.
  const entry = await page.evaluate(() => ({ ...document.querySelector("#history li").dataset }));
  const fields = entry.colmap.split(" ");
  assert.equal(fields.length, 10);
  near(fields.slice(1, 5).map(Number), shown.q, 1e-12, "images.txt q");
  near(fields.slice(5, 8).map(Number), shown.t, 1e-12, "images.txt t");
  assert.equal(fields[9], "0000.jpg");
  assert.deepEqual(JSON.parse(entry.json).cam_from_world, { rotation: shown.q, translation: shown.t });
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#history li button:text('images.txt')")]);
  assert.equal(download.suggestedFilename(), "0000.images.txt");
  assert.equal(readFileSync(await download.path()).toString(), `${entry.colmap}\n\n`);
  // Go to camera: just behind and above the photo's camera, looking where it looks (from the
  // centre itself the nearest lines filled the view).
  await page.click("#goto");
  s = await scene(page);
  const worldFromCam = (q) => {  // the rows of cam_from_world's R: the camera's x, y, z axes in the map
    const [w, x, y, z] = q;
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]];
  };
  const [, camY, camZ] = worldFromCam(api.q);
  const eye = api.center.map((c, i) => c - 0.3 * s.radius * camZ[i] - 0.1 * s.radius * camY[i]);
  near(s.position, eye, 1e-3 * s.radius, "the view behind and above the camera");
  near(s.target, api.center.map((c, i) => c + 0.5 * s.radius * camZ[i]), 1e-3 * s.radius, "looking along its axis");
  near(s.up, camY.map((v) => -v), 1e-6, "the photo's up");
  await page.screenshot({ path: `${shots}/fountain-photo.png` });
  // Fit: the scene the audit recovered and the photo, not the lines (a line runs far beyond
  // its point): the target inside the recovered points' 5-95 % box, the frame smaller.
  await page.click("#fit");
  const fitted = await scene(page);
  const xyz = new Float32Array(points, 0, 3 * lines);
  for (let k = 0; k < 3; ++k) {
    const axis = Array.from({ length: lines }, (_, i) => xyz[3 * i + k]).sort((a, b) => a - b);
    const [lo, hi] = [axis[Math.floor(0.05 * lines)], axis[Math.floor(0.95 * lines)]];
    assert.ok(fitted.target[k] >= lo && fitted.target[k] <= hi, `fit target ${k}: ${fitted.target[k]} outside ${lo}..${hi}`);
  }
  // Top view: the map has no gravity; the localized photo says which way is up.
  assert.equal(await page.isDisabled("#top"), false, "a photo localized: up is known");
  await page.click("#top");
  s = await scene(page);
  const photoUp = camY.map((v) => -v);
  const upDot = s.position.map((v, i) => v - s.target[i]).reduce((a, v, i) => a + v * photoUp[i], 0);
  assert.ok(upDot > 0.99 * Math.hypot(...s.position.map((v, i) => v - s.target[i])), "looking down along the photo's up");
  await page.uncheck("#show-lines");
  assert.equal((await scene(page)).visible, false);
  await page.check("#show-lines");
  await page.fill("#opacity", "0.3");
  await page.dispatchEvent("#opacity", "input");
  assert.equal((await scene(page)).opacity, 0.3);
  await page.click("#reset");

  // ---- one request at a time; an error after a success clears the pose ------
  posts = 0;
  await page.setInputFiles("#photo", photo);
  await page.fill("#camera", camera);
  await page.evaluate(() => { document.querySelector("#localize-button").click(); document.querySelector("#localize-button").click();
                              document.querySelector("#localize").requestSubmit(); });
  await page.waitForFunction(() => document.querySelector("#localize").getAttribute("aria-busy") === "false" && document.querySelector("#pose-q"), null, { timeout: 60000 });
  assert.equal(posts, 1, "three clicks while busy: one request");
  // Checked before the upload: not a photo. The last pose goes too.
  posts = 0;
  await localizeOnPage(page, `${tmp}/not-a-photo.jpg`, camera);
  assert.match(await text(page, "#error"), /not-a-photo\.jpg is not a JPEG or PNG photo/);
  assert.equal(posts, 0, "refused before the upload");
  await assertNoRequestState(page, "a file refused before the upload");
  await localizeOnPage(page, photo, camera);
  await localizeOnPage(page, photo, "PINHOLE 100 100 50 50 50 50");
  assert.match(await text(page, "#error"), /camera is 100x100/);
  await assertNoRequestState(page, "an error after a success");
  assert.ok(!(await page.evaluate(() => [...document.querySelectorAll("#recent-cameras option")].map((o) => o.value)))
    .includes("PINHOLE 100 100 50 50 50 50"), "a camera the server refused is not offered again");

  // ---- EXIF: the photo drawn as the server read it ---------------------------
  await localizeOnPage(page, turnedPhoto, camera);  // the camera of the stored pixels: used as stored
  let o = await page.evaluate(() => ({ ...document.querySelector("#overlay").dataset, w: document.querySelector("#overlay").width, h: document.querySelector("#overlay").height }));
  assert.equal(o.orientation, "stored");
  assert.deepEqual([o.w, o.h], [640, 427]);
  const centreStored = JSON.parse(await page.getAttribute("#pose-center", "data-value"));
  near(centreStored, api.center, 1e-6, "the stored pixels give the original's pose");
  await localizeOnPage(page, turnedPhoto, turnedCamera);  // the camera as displayed: the photo turned
  assert.equal(await text(page, "#error"), "");
  o = await page.evaluate(() => ({ ...document.querySelector("#overlay").dataset, w: document.querySelector("#overlay").width, h: document.querySelector("#overlay").height }));
  assert.equal(o.orientation, "displayed");
  assert.deepEqual([o.w, o.h], [640, 960]);
  const centreTurned = JSON.parse(await page.getAttribute("#pose-center", "data-value"));
  results.exif_centre_difference = Math.hypot(...centreTurned.map((v, i) => v - api.center[i]));
  assert.ok(results.exif_centre_difference < 0.02, `the turned photo's centre: ${results.exif_centre_difference} off`);
  const turnedApi = await apiLocalize(turnedPhoto, turnedCamera, owner);
  for (const [x, y] of turnedApi.inlier_keypoints) assert.ok(x >= 0 && x <= 1024 && y >= 0 && y <= 1536, `keypoint ${x}, ${y} in the turned frame`);
  await page.screenshot({ path: `${shots}/exif-turned.png` });

  // ---- another map: nothing of fountain stays --------------------------------
  await localizeOnPage(page, photo, camera);
  await page.fill("#limit", "100000");
  await openMap(page, "big");
  await assertNoRequestState(page, "another map");
  assert.equal(await page.isHidden("#audit"), true, "fountain's audit is gone");
  assert.equal(await text(page, "#audit-points-count"), "");
  // The owner of a map without an audit is told so, not that the token may not see it.
  assert.match(await text(page, "#privacy-facts-audit"), /^none published with this map \(no ID\.audit\.json next to the map/);
  s = await scene(page);
  assert.equal(s.recovered, 0, "fountain's recovered points are gone");
  assert.equal(s.lines, 100000);
  assert.equal(await page.getAttribute('#maps button[data-map="fountain"]', "aria-pressed"), "false");

  // ---- 100 000 lines on the software renderer: moving at the level of detail ----
  results.fps_moving_100k = Math.round(10 * await page.evaluate(() => window.linecloudFps(2000))) / 10;
  results.lines_per_frame_100k = (await scene(page)).chunk;
  assert.ok(results.fps_moving_100k >= 30, `moving: ${results.fps_moving_100k} fps`);
  // At rest the picture completes, chunk by chunk, every line drawn.
  results.full_picture_ms_100k = Math.round(await page.evaluate(() => window.linecloudFullPictureMs()));
  assert.equal((await scene(page)).drawn, 100000);
  await page.screenshot({ path: `${shots}/big-map.png` });
  // A drag: the view moves, then rests with every line drawn.
  const box = await page.locator("#view canvas").boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 120, box.y + box.height / 2 + 30, { steps: 8 });
  await page.mouse.up();
  await page.waitForTimeout(400);
  const drawn = await page.evaluate(() => document.querySelector("#view canvas") && window.linecloudScene());
  assert.notDeepEqual(drawn.position, s.position, "a drag turns the view");

  // ---- a rate-limited token: the page says when to try again ----------------
  await signIn(page, limited);
  await openMap(page, "fountain");
  await localizeOnPage(page, photo, camera);  // its one localization a minute
  assert.equal(await text(page, "#error"), "");
  await localizeOnPage(page, photo, camera);
  assert.match(await text(page, "#error"), /429: .*try again in \d+ s/);
  await assertNoRequestState(page, "a refused request");

  // ---- another token: nothing of the owner's stays ---------------------------
  await page.fill("#limit", "20000");
  await signIn(page, reader);
  await assertNoRequestState(page, "another token");
  assert.deepEqual(await page.$$eval("#maps button", (b) => b.map((x) => x.dataset.map)), ["fountain"]);
  assert.equal(await page.$$eval("#history li", (l) => l.length), 0, "the owner's queries are gone");
  assert.equal((await scene(page)).lines, 0);
  await openMap(page, "fountain");
  assert.equal(await page.isHidden("#audit"), true);
  s = await scene(page);
  assert.deepEqual([s.lines, s.recovered], [0, 0], "a reader gets neither lines nor the audit");
  assert.match(await text(page, "#view-note"), /not published/);
  assert.match(await text(page, "#privacy-facts-audit"), /^not shown to this token/);
  await localizeOnPage(page, photo, camera);
  near(JSON.parse(await page.getAttribute("#pose-q", "data-value")), shown.q, 1e-6, "reader q");
  assert.equal(await page.getAttribute("#overlay", "data-inliers"), "0", "no correspondences for a reader");
  await page.screenshot({ path: `${shots}/reader.png` });
  // A photo dropped before the camera is typed is kept: the camera, then Localize.
  await page.fill("#camera", "");
  const dropped = await page.evaluateHandle((b) => {
    const d = new DataTransfer();
    d.items.add(new File([Uint8Array.from(atob(b), (c) => c.charCodeAt(0))], "dropped.jpg", { type: "image/jpeg" }));
    return d;
  }, readFileSync(photo).toString("base64"));
  await page.dispatchEvent("#drop", "drop", { dataTransfer: dropped });
  await page.waitForFunction(() => document.querySelector("#photo-error").textContent.includes("give the camera of dropped.jpg"));
  assert.equal(await page.inputValue("#photo"), "", "no other file's name beside the dropped photo");
  assert.match(await text(page, "#drop"), /dropped\.jpg/);
  await page.fill("#camera", camera);
  await page.click("#localize-button");
  await page.waitForFunction(() => document.querySelector("#localize").getAttribute("aria-busy") === "false" &&
                                   (document.querySelector("#pose-q") || document.querySelector("#error").textContent),
                             null, { timeout: 60000 });
  assert.ok(await page.$("#pose-q"), `the dropped photo, once the camera is given: ${await text(page, "#error")}`);
  // Sign out: the token forgotten, nothing shown.
  await page.click("#logout-button");
  assert.equal(await page.$$eval("#maps button", (b) => b.length), 0);
  assert.equal(await page.evaluate(() => sessionStorage.getItem("linecloud-token")), null);
  await assertNoRequestState(page, "signed out");
  assert.deepEqual(errors, [], `page errors: ${errors.join("; ")}`);
  assert.deepEqual(refused, [], "asked only for what the token may fetch");

  // ---- keyboard only: sign in, open a map, turn the view, a photo, localize ---
  await page.close();
  const kb = await context.newPage();
  kb.on("pageerror", (e) => errors.push(e.message));
  await kb.bringToFront();
  // File choosers are intercepted from now on (asked for at the key press, the interception could
  // come after the dialog).
  let chooserSeen;
  const chooserShown = new Promise((resolve) => { chooserSeen = resolve; });
  kb.on("filechooser", (fc) => chooserSeen(fc));
  await kb.goto(base + "/");
  await tabTo(kb, "#token");
  await kb.keyboard.type(owner);
  await kb.keyboard.press("Enter");
  await kb.waitForSelector('#maps button[data-map="fountain"]');
  await tabTo(kb, '#maps button[data-map="fountain"]');
  await kb.keyboard.press("Enter");
  await kb.waitForFunction(() => document.querySelector("#status").textContent === "map fountain open");
  await tabTo(kb, "#view");
  const before = (await scene(kb)).position;
  for (let i = 0; i < 5; ++i) await kb.keyboard.press("ArrowLeft");
  assert.notDeepEqual((await scene(kb)).position, before, "arrow keys turn the view");
  await tabTo(kb, "#drop");
  await kb.keyboard.press("Enter");
  const chooser = await Promise.race([chooserShown, new Promise((_, reject) =>
    setTimeout(() => reject(new Error("Enter on the drop zone opened no file chooser")), 20000))]);
  await chooser.setFiles(photo);
  await tabTo(kb, "#camera");
  await kb.keyboard.type(camera);
  await kb.keyboard.press("Enter");
  await kb.waitForSelector("#pose-q", { timeout: 60000 });
  near(JSON.parse(await kb.getAttribute("#pose-q", "data-value")), shown.q, 1e-6, "keyboard q");
  await kb.close();

  // ---- a phone: 390 px, nothing off screen, the canvas follows its box --------
  const phone = await browser.newPage({ viewport: { width: 390, height: 844 }, deviceScaleFactor: 2 });
  phone.on("pageerror", (e) => errors.push(e.message));
  await phone.goto(base + "/");
  await signIn(phone, owner);
  await openMap(phone, "fountain");
  // The photo panel right after the maps (the map's details folded), not two screens down.
  results.phone_photo_panel_top = await phone.evaluate(() => document.querySelector("#photo-panel").getBoundingClientRect().top + window.scrollY);
  assert.ok(results.phone_photo_panel_top < 844, `the photo panel starts ${results.phone_photo_panel_top} px down on an 844 px phone`);
  await localizeOnPage(phone, photo, camera);
  const layout = await phone.evaluate(() => ({
    scroll: document.documentElement.scrollWidth, client: document.documentElement.clientWidth,
    view: document.querySelector("#view").clientWidth, canvas: document.querySelector("#view canvas").width,
    photo: document.querySelector("#photo-panel").getBoundingClientRect().right,
    overlay: document.querySelector("#overlay").getBoundingClientRect().right,
  }));
  results.phone = layout;
  assert.ok(layout.scroll <= 390, `the page is ${layout.scroll} px wide on a 390 px phone`);
  assert.ok(layout.photo <= 390 && layout.overlay <= 390, `photo panel right edge ${layout.photo}`);
  assert.equal(layout.canvas, layout.view, "the canvas is as wide as its box");
  assert.deepEqual(await phone.evaluate(contrastProblems), []);
  await phone.screenshot({ path: `${shots}/phone.png`, fullPage: true });
  // An error about the photo shows where the user acted, not only in the alert line far above.
  await localizeOnPage(phone, `${tmp}/not-a-photo.jpg`, camera);
  const photoError = await phone.evaluate(() => {
    const e = document.querySelector("#photo-error"), b = document.querySelector("#localize-button");
    return { text: e.textContent, gap: e.getBoundingClientRect().top - b.getBoundingClientRect().bottom };
  });
  assert.match(photoError.text, /not a JPEG or PNG photo/);
  assert.ok(photoError.gap >= 0 && photoError.gap < 120, `the photo error ${photoError.gap} px below the Localize button`);
  await phone.setViewportSize({ width: 844, height: 390 });  // turned
  await phone.waitForTimeout(300);
  const turned = await phone.evaluate(() => ({ view: document.querySelector("#view").clientWidth,
                                                canvas: document.querySelector("#view canvas").width,
                                                scroll: document.documentElement.scrollWidth }));
  assert.equal(turned.canvas, turned.view, "the canvas follows a turned phone");
  assert.ok(turned.scroll <= 844);
  await phone.close();
  assert.deepEqual(errors, [], `page errors: ${errors.join("; ")}`);
} finally {
  await browser.close();
  server.kill("SIGTERM");
}
writeFileSync(`${shots}/results.json`, JSON.stringify(results, null, 2));
console.log(`console test passed: ${JSON.stringify(results)}`);
