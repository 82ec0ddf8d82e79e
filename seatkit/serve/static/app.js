// seatkit serve: the page. Talks to the JSON API of seatkit/serve/app.py.
import * as THREE from "three";
import { OrbitControls } from "/static/vendor/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const state = {
  options: null,
  people: [],          // per person in seat order: {model, params, pose, upload, frame, poseData, angles}
  current: 0,          // the person the Pose, Joints and Body controls edit
  pose: null,          // the current person's pose: {pose, angles (21x3 deg), translation, supported, description}
  upload: null,        // the current person's uploaded file in the server's upload folder
  sliders: {},         // key -> slider spec
  clientSeq: 0,        // newest request made by this page
  shownSeq: 0,         // request whose design is on screen
  design: null,        // report of the design on screen
  designsShown: 0,
  stale: false,        // the design on screen is not the one asked for last (a refusal, an error)
  frame: null,         // {centre, size} the camera is framed on
  previewDraws: [],    // seconds each preview of the newest request took to draw
};
window.seatkit = state; // read by the browser test

// ------------------------------------------------------------------ API
// Every request asks for errors in the body (?errors=200): a refusal or a superseded request is an
// expected answer, and a browser logs any non-2xx answer as a console error.
async function api(path, options = {}) {
  const url = path + (path.includes("?") ? "&" : "?") + "errors=200";
  const response = await fetch(url, options);
  const headers = performance.now();
  let data = null;
  try { data = await response.json(); } catch (e) { data = { error: `HTTP ${response.status}` }; }
  const status = data && data.status ? data.status : response.status;
  return { ok: response.ok && !(data && data.status), status, data, times: { headers, parsed: performance.now() } };
}
const postJSON = (path, body) => api(path, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });

// ------------------------------------------------------------------ 3D view
const view = $("view");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f3f0);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 50);
camera.position.set(1.9, 1.3, 2.1); // front-left: the body faces +Z, +X is its left
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0.6, 0);
controls.addEventListener("change", render);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8070, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(2, 4, 3);
scene.add(sun);
const grid = new THREE.GridHelper(3, 30, 0xb9b4aa, 0xd9d5cc);
scene.add(grid);
const designGroup = new THREE.Group();
scene.add(designGroup);

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false);
  renderer.domElement.style.width = w + "px";
  renderer.domElement.style.height = h + "px";
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  render();
}
// One frame per change of the scene: while a design or a preview is put in the scene (its chair, the
// view options, the camera framed on it), the frames asked for are drawn once, at its end. Every
// frame asked for is drawn in full, and with software WebGL on the cores the server designs on.
let holding = 0, held = false;
function render() {
  if (holding) { held = true; return; }
  held = false;
  renderer.render(scene, camera);
}
function drawOnce(change) {
  holding++;
  try { change(); } finally { holding--; }
  if (!holding && held) render();
}
window.addEventListener("resize", resize);

function decode(b64, Type) {
  const text = atob(b64);
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return new Type(bytes.buffer);
}

// One material per kind, made once and kept for every design and preview. A material disposed
// with its mesh takes its compiled shader program with it, and compiling it again (with software
// WebGL: in Chromium's GPU process, on the cores the server designs on) costs more than the frame.
const MATERIALS = {
  body: new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.8 }),
  chair: new THREE.MeshStandardMaterial({ color: 0x6f9fc8, roughness: 0.55, metalness: 0.0, side: THREE.DoubleSide, transparent: true }),
  cage: new THREE.LineBasicMaterial({ color: 0x1d3b57 }),
};

// The materials as a design shows (stale: greyed, see-through, for a design that is no longer the
// one asked for); a property the shader program depends on is changed only when it differs.
function styleMaterials(stale) {
  const chairOpacity = Number(document.querySelector("input[name=chair]:checked").value);
  for (const [kind, m] of Object.entries(MATERIALS)) {
    const transparent = stale || kind === "chair";
    const vertexColors = kind === "body" && !stale;
    if (m.transparent !== transparent || m.vertexColors !== vertexColors) {
      m.transparent = transparent;
      m.vertexColors = vertexColors;
      m.needsUpdate = true;
    }
    m.opacity = stale ? 0.25 : kind === "chair" ? chairOpacity : 1;
  }
}

// Pressure colours: grey where there is no contact, then yellow -> orange -> red -> purple up to the
// largest value shown (the scale never clips what it shows).
const RAMP = [[0.0, [1.0, 0.82, 0.15]], [0.35, [0.97, 0.5, 0.1]], [0.7, [0.84, 0.16, 0.12]], [1.0, [0.45, 0.02, 0.25]]];
function ramp(t) {
  for (let i = 1; i < RAMP.length; i++) {
    if (t <= RAMP[i][0]) {
      const [t0, c0] = RAMP[i - 1], [t1, c1] = RAMP[i];
      const u = (t - t0) / (t1 - t0);
      return c0.map((v, k) => v + u * (c1[k] - v));
    }
  }
  return RAMP[RAMP.length - 1][1];
}

function showView(v) { drawOnce(() => putInScene(v)); }
function putInScene(v) {
  // a preview of the posed body alone keeps the previous chair until the new one is fitted; the
  // template's preview (sent without the bodies) keeps the posed bodies drawn
  for (const child of [...designGroup.children]) {
    if ((child.name === "body" && v.bodies) || (child.name !== "body" && v.surface)) {
      child.geometry.dispose(); // the materials are kept (MATERIALS)
      designGroup.remove(child);
    }
  }
  if (v.bodies) {
    const pmax = Math.max(1e-9, ...v.bodies.map((b) => b.max_pressure_pa));
    for (const b of v.bodies) {
      const g = new THREE.BufferGeometry();
      const pos = decode(b.positions, Float32Array);
      const p = decode(b.pressure, Float32Array);
      const colors = new Float32Array(pos.length);
      for (let i = 0; i < p.length; i++) {
        const c = p[i] > 0.5 ? ramp(Math.min(1, p[i] / pmax)) : [0.78, 0.79, 0.8];
        colors.set(c, 3 * i);
      }
      g.setAttribute("position", new THREE.BufferAttribute(pos, 3));
      g.setAttribute("color", new THREE.BufferAttribute(colors, 3));
      g.setIndex(new THREE.BufferAttribute(decode(b.faces, Uint32Array), 1));
      g.computeVertexNormals();
      const mesh = new THREE.Mesh(g, MATERIALS.body);
      mesh.name = "body";
      designGroup.add(mesh);
    }
    $("legend-max").textContent = (pmax / 1000).toFixed(1);
    $("legend-title").textContent = v.bodies[0].pressure_kind === "contact"
      ? "relative importance on the designed surface (paper's model), kPa" : "relative importance, supported everywhere (paper's model), kPa";
  }
  if (v.surface) addChair(v);
  styleMaterials(false);
  if (v.bounds) reframe(v.bounds);
  render();
}

// Frame the camera on a finished design's bounds (a bench is wider than a chair): kept from the
// same direction, moved only when the design leaves the frame or is much smaller than it.
function reframe(bounds) {
  const box = new THREE.Box3(new THREE.Vector3(...bounds[0]), new THREE.Vector3(...bounds[1]));
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
  const f = state.frame;
  if (f) {
    const room = new THREE.Box3().setFromCenterAndSize(f.centre, new THREE.Vector3(1, 1, 1).multiplyScalar(f.size / Math.sqrt(3) + 0.05));
    if (room.containsBox(box) && size > 0.7 * f.size) return;
  }
  const direction = f ? camera.position.clone().sub(controls.target).normalize().toArray() : [1.0, 0.35, 0.55]; // first: from the body's left, a little in front and above
  state.frame = { centre, size, bounds };
  lookFrom(direction);
}

function lookFrom(direction) {
  if (!state.frame) return;
  const { centre, size } = state.frame;
  drawOnce(() => {
    controls.target.copy(centre);
    camera.position.copy(centre).add(new THREE.Vector3(...direction).normalize().multiplyScalar(size * 1.5));
    controls.update();
    render();
  });
}
for (const b of document.querySelectorAll("#view-options button")) b.addEventListener("click", () => lookFrom(b.dataset.view.split(",").map(Number)));

function addChair(v) {
  const s = new THREE.BufferGeometry();
  s.setAttribute("position", new THREE.BufferAttribute(decode(v.surface.positions, Float32Array), 3));
  s.setAttribute("normal", new THREE.BufferAttribute(decode(v.surface.normals, Float32Array), 3));
  s.setIndex(new THREE.BufferAttribute(decode(v.surface.faces, Uint32Array), 1));
  const chair = new THREE.Mesh(s, MATERIALS.chair);
  chair.name = "chair";
  designGroup.add(chair);
  const c = new THREE.BufferGeometry();
  c.setAttribute("position", new THREE.BufferAttribute(decode(v.cage.positions, Float32Array), 3));
  c.setIndex(new THREE.BufferAttribute(decode(v.cage.edges, Uint32Array), 1));
  const cage = new THREE.LineSegments(c, MATERIALS.cage);
  cage.name = "cage";
  designGroup.add(cage);
  applyViewOptions();
}

function applyViewOptions() {
  const opacity = Number(document.querySelector("input[name=chair]:checked").value);
  const chair = designGroup.getObjectByName("chair");
  if (chair) {
    chair.visible = opacity > 0;
    chair.material.opacity = opacity;
    chair.material.depthWrite = opacity >= 1; // see-through: the body behind it stays visible
  }
  const cage = designGroup.getObjectByName("cage");
  if (cage) cage.visible = $("show-cage").checked;
  render();
}
for (const input of document.querySelectorAll("#view-options input")) input.addEventListener("change", applyViewOptions);

// ------------------------------------------------------------------ progress
const STAGES = ["check", "bodies", "pressure", "template", "refine:optimize", "refine:catmull-clark-fit", "surface", "evaluate"];
let polling = null;
let progressShown = "";
// The progress box sits over the 3D view: each change of it is a new frame of the page. It is
// changed only when what it says changes, and without an animation (a frame for every step).
function setProgress(text, fraction, cls = "") {
  const key = `${cls}|${text}|${Math.round(100 * fraction)}`;
  if (key === progressShown) return;
  progressShown = key;
  $("progress").className = cls;
  $("progress-text").textContent = text;
  $("progress-bar").style.transform = `scaleX(${Math.min(1, Math.max(0, fraction)).toFixed(2)})`;
}
// While a design runs, the page asks for the status, which the server answers when it changes (a
// stage starts, a preview is made: GET /api/status?since=VERSION), and shows the stage; when the
// design has made something new (the posed body, then the template's cage) it draws that preview,
// labelled, until the finished design replaces it. Only the newest request's previews are drawn,
// and never after its finished design: the design's answer ends the polling and cancels a status
// or preview request still on its way.
const PREVIEW_LABEL = { posed: "new pose (pressure supported everywhere)", template: "template cage; refining" };
function startPolling(label, request, seq) {
  stopPolling();
  const t0 = performance.now();
  const ticket = new AbortController();
  polling = ticket;
  const live = () => polling === ticket;
  setProgress(`${label}: sending`, 0.02, "running");
  (async () => {
    let version = "", drawn = null;
    while (live()) {
      let r;
      try {
        r = await api(`/api/status?since=${version}`, { signal: ticket.signal });
      } catch (e) { return; } // cancelled: the design's answer is in
      if (!live()) return;
      if (!r.ok) { await new Promise((done) => setTimeout(done, 250)); continue; }
      version = r.data.version;
      const stage = r.data.stage;
      if (stage === "idle" || r.data.request !== request) continue;
      const i = STAGES.indexOf(stage);
      const secs = ((performance.now() - t0) / 1000).toFixed(1);
      setProgress(`${label}: ${stage} (${secs} s)`, i < 0 ? 0.5 : (i + 1) / (STAGES.length + 1), "running");
      const preview = r.data.preview;
      if (!preview || preview === drawn) continue;
      // the body is sent once: the template's preview of the same request adds its cage and surface
      const only = drawn ? "&bodies=0" : "";
      let p;
      try {
        p = await api(`/api/preview?request=${encodeURIComponent(request)}${only}`, { signal: ticket.signal });
      } catch (e) { return; }
      if (!live() || seq !== state.clientSeq || state.shownSeq === seq || !p.ok) continue;
      drawn = p.data.stage;
      const drawStart = performance.now();
      showView(p.data);
      state.previewDraws.push((performance.now() - drawStart) / 1000); // this design's previews drawn, and what each took
      state.previewsShown = (state.previewsShown || 0) + 1;
      state.lastPreview = { seq, stage: p.data.stage, seconds: (performance.now() - t0) / 1000 };
      setProgress(`${PREVIEW_LABEL[p.data.stage] || p.data.stage} (${state.lastPreview.seconds.toFixed(1)} s)`, (i + 1) / (STAGES.length + 1), "running");
    }
  })();
}
function stopPolling() { if (polling) polling.abort(); polling = null; }

// ------------------------------------------------------------------ controls
function option(select, value, text) {
  const o = document.createElement("option");
  o.value = value; o.textContent = text;
  select.appendChild(o);
}

// Parameter fields: each shows the value the design uses (a body's own mass and height come from its
// model); a blank field means "the model's own" (its proportions, anny's height). Parameters marked
// advanced (the algorithm's internals) go into the fold below the others.
function paramInputs(container, params, prefix, values, onChange) {
  container.innerHTML = "";
  const fold = document.createElement("details");
  fold.className = "advanced";
  const summary = document.createElement("summary");
  summary.textContent = "advanced";
  fold.appendChild(summary);
  for (const p of params) {
    const row = document.createElement("label");
    row.className = "param";
    const name = document.createElement("span");
    name.textContent = p.unit && p.unit !== "1" ? `${p.label} (${p.unit})` : p.label;
    name.title = p.description || "";
    let input;
    const value = values && p.key in values ? values[p.key] : p.default;
    if (p.enum) {
      input = document.createElement("select");
      for (const e of p.enum) option(input, e, e);
      if (value != null) input.value = value;
    } else {
      input = document.createElement("input");
      input.type = "number";
      input.step = "any";
      if (p.minimum != null) input.min = p.minimum;
      if (p.maximum != null) input.max = p.maximum;
      input.placeholder = p.placeholder || "own";
      if (value != null) input.value = value;
    }
    input.dataset.key = p.key;
    input.dataset.default = p.default == null ? "" : String(p.default);
    input.id = `${prefix}-${p.key}`;
    input.title = p.description || "";
    input.addEventListener("change", onChange);
    row.append(name, input);
    (p.advanced ? fold : container).appendChild(row);
  }
  if (fold.children.length > 1) container.appendChild(fold);
}

// Every field with a value: the server drops a value equal to the model's own (the same body, the
// same design), so what the field shows is what the design uses.
function fieldValues(container, onlyChanged = false) {
  const out = {};
  for (const input of container.querySelectorAll("input, select")) {
    if (input.value === "" || (onlyChanged && input.value === input.dataset.default)) continue;
    out[input.dataset.key] = input.type === "number" ? Number(input.value) : input.value;
  }
  return out;
}

const RANGES = { "trunk-recline": [-30, 80], hip: [-30, 150], knee: [0, 160], shoulder: [-60, 180], elbow: [0, 150] };
function sliderValue(spec, angles) { return spec.sign * angles[state.pose.segments.indexOf(spec.segment)][spec.axis]; }

function buildSliders() {
  const box = $("sliders");
  box.innerHTML = "";
  for (const spec of state.options.sliders) {
    state.sliders[spec.key] = spec;
    const row = document.createElement("div");
    row.className = "slider";
    const name = document.createElement("span");
    name.className = "name"; name.textContent = spec.label;
    const input = document.createElement("input");
    input.type = "range"; input.step = "1"; input.id = `slider-${spec.key}`;
    input.dataset.key = spec.key;
    const out = document.createElement("output");
    out.id = `out-${spec.key}`;
    input.addEventListener("input", () => onSlider(spec, input));
    input.addEventListener("change", () => { person().angles = currentAngles(); requestDesign(); });
    row.append(name, input, out);
    box.appendChild(row);
  }
}

// The sliders show the current person's joints: the pose's, or where this person's sliders were left.
function setSliders(angles = null) {
  for (const spec of Object.values(state.sliders)) {
    const input = $(`slider-${spec.key}`);
    const start = sliderValue(spec, state.pose.angles);
    const v = angles ? sliderValue(spec, angles.angles) : start;
    const [lo, hi] = RANGES[spec.key] || RANGES[spec.key.split("-")[0]];
    input.min = Math.min(lo, Math.floor(Math.min(v, start))); input.max = Math.max(hi, Math.ceil(Math.max(v, start)));
    input.value = v;
    input.dataset.last = String(v);
    $(`out-${spec.key}`).textContent = `${Math.round(v)}°`;
  }
}

function onSlider(spec, input) {
  const v = Number(input.value);
  if (spec.key === "trunk-recline") {
    // keep the thighs: the hip flexion takes the recline's change
    const d = v - Number(input.dataset.last);
    for (const k of ["hip-right", "hip-left"]) {
      const h = $(`slider-${k}`);
      h.value = Number(h.value) - d;
      h.dataset.last = h.value;
      $(`out-${k}`).textContent = `${Math.round(Number(h.value))}°`;
    }
  }
  input.dataset.last = String(v);
  $(`out-${spec.key}`).textContent = `${Math.round(v)}°`;
}

function currentAngles() {
  const angles = state.pose.angles.map((row) => row.slice());
  let changed = false;
  for (const spec of Object.values(state.sliders)) {
    const v = Number($(`slider-${spec.key}`).value);
    const i = state.pose.segments.indexOf(spec.segment);
    if (Math.abs(v - sliderValue(spec, state.pose.angles)) > 1e-9) {
      angles[i][spec.axis] = spec.sign * v;
      changed = true;
    }
  }
  return { angles, changed };
}

// ------------------------------------------------------------------ people
function person() { return state.people[state.current]; }
function modelParams(model) { return state.options.bodies.find((b) => b.name === model).params; }
function newPerson(from) {
  return { model: from.model, params: {}, pose: from.pose, upload: from.upload, frame: from.frame, poseData: from.poseData, angles: from.angles, made: null };
}

function describePerson(p, i) {
  const shown = state.options.poses.find((x) => x.name === p.pose);
  const pose = p.upload || (shown ? shown.name : p.pose);
  return `${i + 1}: ${p.model}, ${pose}${p.angles && p.angles.changed ? " (joints moved)" : ""}`;
}

function showPeopleList() {
  const n = state.people.length;
  $("person-row").hidden = n <= 1;
  const sel = $("person-select");
  sel.innerHTML = "";
  state.people.forEach((p, i) => option(sel, String(i), describePerson(p, i)));
  sel.value = String(state.current);
  for (const h of document.querySelectorAll(".who")) h.textContent = n > 1 ? ` of person ${state.current + 1}` : "";
}

// Show the current person in the Pose, Joints and Body controls.
function showPerson() {
  const p = person();
  $("body-select").value = p.model;
  paramInputs($("body-params"), modelParams(p.model), "body", p.params, onBodyParams);
  $("pose-select").value = p.upload ? $("pose-select").value : p.pose;
  $("frame-row").hidden = !(p.upload && p.upload.endsWith(".bvh"));
  $("bvh-frame").value = p.frame || 0;
  state.upload = p.upload;
  state.pose = p.poseData;
  if (state.pose) {
    $("pose-note").textContent = (state.pose.description || "") + (state.pose.supported === false ? " (listed as not supported by the method)" : "");
    setSliders(p.angles);
  }
  showPeopleList();
}

function onBodyParams() {
  person().params = fieldValues($("body-params"));
  requestDesign();
}

function setPeople(n) {
  while (state.people.length < n) state.people.push(newPerson(state.people[state.people.length - 1]));
  state.people.length = n;
  state.current = Math.min(state.current, n - 1);
  showPerson();
}

function bodyEntry(p) {
  return { model: p.model, params: p.params };
}

async function loadPose() {
  const p = person();
  const pose = p.upload || p.pose;
  const q = new URLSearchParams({ pose, frame: String(p.frame || 0), model: p.model, params: JSON.stringify(p.params) });
  const r = await api(`/api/pose?${q}`);
  if (!r.ok) { showError(r.data.error); return false; }
  p.poseData = r.data;
  p.angles = null;
  p.made = null;
  state.pose = r.data;
  $("pose-note").textContent = (r.data.description || "") + (r.data.supported === false ? " (listed as not supported by the method)" : "");
  setSliders();
  showPeopleList();
  return true;
}

// ------------------------------------------------------------------ designs
// A refusal or an error: the design on screen is no longer the one asked for. It is greyed, and the
// figures and the files are labelled with the design they belong to.
function markStale(stale) {
  state.stale = stale;
  document.body.classList.toggle("stale", stale);
  styleMaterials(stale);
  if (!stale) applyViewOptions();
  showDesignOf();
  render();
}

function designLabel(report) {
  const people = report.people || [];
  const who = people.map((p) => `${p.model} ${p.mass_kg.toFixed(1)} kg${p.height_m ? ` ${p.height_m.toFixed(2)} m` : ""}, ${p.pose}`).join("; ");
  return `${report.template}: ${who}`;
}

function showDesignOf() {
  const d = state.design;
  const label = d ? designLabel(d) : "";
  $("design-of").textContent = !d ? "" : state.stale
    ? `Not the input asked for: the figures, the view and the files below are of the previous design (${label}).`
    : `Figures and files of: ${label}`;
  $("design-of").className = state.stale ? "stale-note" : "note";
  $("make-files").textContent = state.stale ? "Make files for the previous design" : "Make files for this design";
}

function showError(message, unsupported = false) {
  $("refusal").hidden = false;
  $("refusal").querySelector("h2").textContent = unsupported ? "This pose cannot be supported" : "This input cannot be used";
  $("refusal-text").textContent = message;
  setProgress(unsupported ? "refused: see the reason on the right" : "error: see the message on the right", 1, "error");
  // the view goes back to the design the figures belong to (a preview of the refused input may be on it)
  if (state.lastView) showView(state.lastView);
  if (state.design) markStale(true);
}

function fmt(x, scale) { return x == null ? "-" : (x * scale).toFixed(2); }

// Table 1, one table per person (a bench seats several, each with their own figures).
function showReport(report) {
  const box = $("tables");
  box.innerHTML = "";
  const m = report.metrics || {};
  const people = report.people || [{}];
  people.forEach((who, i) => {
    const ours = (m.ours || [])[i] || {};
    const base = (m.baseline || [])[i] || null;
    const table = document.createElement("table");
    table.className = "table1";
    table.id = i === 0 ? "table1" : `table1-${i + 1}`;
    const caption = document.createElement("caption");
    caption.textContent = people.length > 1 ? `Person ${i + 1}: ${who.model}, ${who.mass_kg != null ? who.mass_kg.toFixed(1) : "?"} kg, ${who.pose}` : "";
    const head = document.createElement("thead");
    head.innerHTML = "<tr><th></th><th>ours</th><th></th></tr>";
    head.querySelectorAll("th")[2].textContent = m.baseline_template || "flat patch";
    const tbody = document.createElement("tbody");
    for (const col of report.table_columns) {
      const tr = document.createElement("tr");
      const a = ours[col.key], b = base ? base[col.key] : null;
      const cells = [`${col.label} (${col.unit})`, fmt(a, col.scale), base ? fmt(b, col.scale) : "…"];
      cells.forEach((text, k) => {
        const td = document.createElement("td");
        td.textContent = text;
        if (k === 1 && base && a != null && b != null && a < b) td.className = "better";
        tr.appendChild(td);
      });
      tbody.appendChild(tr);
    }
    table.append(caption, head, tbody);
    box.appendChild(table);
  });
  const base = (m.baseline || [])[0];
  $("baseline-note").textContent = report.evaluated === false
    ? "The design is shown first; our figures follow (evaluating), then the baseline's when the sliders rest."
    : base ? "Lower is better; bold where our design beats the baseline."
    : "The baseline is fitted when the sliders rest.";
  const facts = $("facts");
  facts.innerHTML = "";
  const t = report.seconds || {};
  const rows = [
    ["template", report.template],
    ["cage", `${report.control_mesh.vertices} vertices, ${report.control_mesh.faces} faces`],
    ["special cases", (report.special_cases || []).filter((c) => c.taken).map((c) => c.case).join(", ") || "none taken"],
    ["supported", (m.supported_segments || []).join(", ")],
    ["design", t.design != null ? `${t.design.toFixed(2)} s` : "from memory"],
    ["evaluation", t.evaluate != null ? `${t.evaluate.toFixed(2)} s` : "-"],
  ];
  if (t.baseline != null) rows.push(["baseline", `${t.baseline.toFixed(2)} s`]);
  // the seat beside the person (report.json metrics.person_fit, ANSI/HFES 100 relations; docs/bodies.md)
  const fit = (m.person_fit || [])[0];
  const metres = (x) => (x == null ? "-" : `${x.toFixed(3)} m`);
  if (fit && fit.popliteal_height_m != null) {
    rows.push(["seat height", `${metres(fit.seat_height_m)} (popliteal height ${metres(fit.popliteal_height_m)} + ${(fit.shoe_allowance_m * 1000).toFixed(0)} mm shoes = ${metres(fit.seat_height_for_shoes_m)})`]);
    rows.push(["seat depth", `${metres(fit.seat_depth_m)} (buttock-popliteal length ${metres(fit.buttock_popliteal_length_m)})`]);
  }
  for (const [k, v] of rows) {
    const dt = document.createElement("dt"); dt.textContent = k;
    const dd = document.createElement("dd"); dd.textContent = v;
    facts.append(dt, dd);
  }
  showDownloads(report);
  showDesignOf();
}

function showDownloads(report) {
  const ul = $("downloads");
  ul.innerHTML = "";
  if (!report.files) return;
  const labels = { usd: "USD (Catmull-Clark cage, usda)", usdc: "USD (usdc)", body_ply: "body PLY (pressure colours)", surface_ply: "PLY surface", design: "design.npz", cage_obj: "OBJ cage", surface_obj: "OBJ surface", surface_stl: "STL surface", surface_glb: "GLB surface", recipe_zip: "recipe (zip: recipe.yaml + pose)", recipe_yaml: "recipe.yaml", report_html: "report (HTML)" };
  for (const [role, url] of Object.entries(report.files)) {
    const li = document.createElement("li");
    const a = document.createElement("a");
    a.href = url; a.textContent = labels[role] || url.split("/").pop();
    a.setAttribute("download", "");
    li.appendChild(a);
    ul.appendChild(li);
  }
}

// A person's pose as the recipe names it: the library pose or upload, or (joints moved) a pose file
// made from the sliders, made once per set of angles.
async function personPose(p, seq) {
  const pose = p.upload || p.pose;
  if (!p.angles || !p.angles.changed) return pose;
  const key = JSON.stringify(p.angles.angles);
  if (p.made && p.made.key === key) return p.made.name;
  const r = await postJSON("/api/pose", { angles: p.angles.angles, translation: p.poseData.translation, description: `${pose}, joints moved in seatkit serve` });
  if (!r.ok) throw new Error(r.data.error);
  p.made = { key, name: r.data.pose };
  return r.data.pose;
}

let baselineTimer = null;
async function requestDesign() {
  if (!state.pose) return;
  const seq = ++state.clientSeq;
  clearTimeout(baselineTimer);
  state.previewDraws = [];
  const started = performance.now();
  const request = `${Date.now().toString(36)}-${seq}`;
  startPolling("designing", request, seq);
  const bodies = [];
  try {
    for (const p of state.people) {
      const pose = await personPose(p, seq);
      const entry = { ...bodyEntry(p), pose };
      if (pose.endsWith(".bvh")) entry.frame = Number(p.frame || 0);
      bodies.push(entry);
    }
  } catch (e) {
    if (seq !== state.clientSeq) return;
    stopPolling(); showError(e.message); return;
  }
  if (seq !== state.clientSeq) return;
  const recipe = { template: $("template-select").value, bodies };
  // only what differs from the template's own values; a designer option is a step option
  // ("steps.STEP.OPTION"), set as a recipe sets it: template_params: {steps: {STEP: {OPTION: value}}}
  const tp = {};
  for (const [k, v] of Object.entries(fieldValues($("template-params"), true))) {
    if (!k.startsWith("steps.")) { tp[k] = v; continue; }
    const cut = k.lastIndexOf(".");
    const step = k.slice(6, cut);
    ((tp.steps = tp.steps || {})[step] = tp.steps[step] || {})[k.slice(cut + 1)] = v;
  }
  if (Object.keys(tp).length) recipe.template_params = tp;
  // the design first (drawn as soon as it exists), then our evaluation (the contact pressure
  // colours, Table 1), then, once the sliders rest, the baseline's figures beside ours
  const r = await api("/api/design?files=0&baseline=0&evaluate=0&view=1", { method: "POST", headers: { "Content-Type": "application/json", "X-Request-Id": request }, body: JSON.stringify(recipe) });
  if (seq !== state.clientSeq) return; // a newer request was made: never show a stale design
  stopPolling();
  if (r.status === 409) {
    // this page's newest request, superseded on the server by an earlier one of this page that
    // reached it later (the server numbers requests as they arrive): asked again, it is the newest
    requestDesign();
    return;
  }
  if (!r.ok) {
    showError(r.data.error, r.data.kind === "unsupported");
    return;
  }
  state.lastAnswer = (performance.now() - started) / 1000; // the design's answer parsed, before drawing it (no WebGL in it)
  state.lastAnswerTimes = { started, headers: r.times.headers, parsed: r.times.parsed }; // page clock (ms), for the benchmark
  $("refusal").hidden = true;
  state.design = r.data;
  state.shownSeq = seq;
  state.stale = false;
  document.body.classList.remove("stale");
  const drawStart = performance.now();
  showView(r.data.view);
  state.lastDraw = (performance.now() - drawStart) / 1000; // building the meshes and one frame (software WebGL here)
  state.lastView = r.data.view;
  delete r.data.view;
  showReport(r.data);
  state.designsShown += 1;
  const secs = (performance.now() - started) / 1000;
  state.lastRoundTrip = secs;
  const serverSeq = r.data.request_seq;
  let evaluated = secs;
  if (!r.data.evaluated) {
    setProgress(`design shown in ${secs.toFixed(2)} s; evaluating (contact pressure, Table 1)`, 0.9, "running");
    const e = await api(`/api/design/${r.data.id}/evaluate?seq=${serverSeq}&view=1`, { method: "POST" });
    if (seq !== state.clientSeq) return; // superseded meanwhile (the server answers 409): the newer design comes
    if (!e.ok) { if (e.status !== 409) setProgress(`evaluation: ${e.data.error}`, 1, "error"); return; }
    state.design = e.data;
    showView(e.data.view);
    state.lastView = e.data.view;
    delete e.data.view;
    showReport(e.data);
    evaluated = (performance.now() - started) / 1000;
  }
  state.lastEvaluated = evaluated;
  setProgress(`design shown in ${secs.toFixed(2)} s, evaluated after ${evaluated.toFixed(2)} s`, 1, "idle");
  baselineTimer = setTimeout(() => requestBaseline(seq, r.data.id, serverSeq), 700);
}

async function requestBaseline(seq, id, serverSeq) {
  if (seq !== state.clientSeq) return;
  setProgress("fitting the flat-patch baseline", 0.5, "running");
  // the server skips it if a newer design request has arrived meanwhile (409)
  const r = await api(`/api/design/${id}/baseline?seq=${serverSeq}`, { method: "POST" });
  if (seq !== state.clientSeq) return;
  if (!r.ok) { if (r.status !== 409) setProgress(`baseline: ${r.data.error}`, 1, "error"); return; }
  state.design = r.data;
  showReport(r.data);
  setProgress("design and baseline shown", 1, "idle");
}

async function makeFiles() {
  if (!state.design) return;
  const id = state.design.id;
  setProgress("writing the files", 0.5, "running");
  const r = await api(`/api/design/${id}/files`, { method: "POST" });
  if (!r.ok) { setProgress(`files: ${r.data.error}`, 1, "error"); return; }
  if (state.design && state.design.id === id) { state.design = r.data; showReport(r.data); }
  setProgress("files ready: see Files", 1, "idle");
}

async function onUpload(event) {
  const file = event.target.files[0];
  if (!file) return;
  if (file.size > state.options.max_upload_bytes) { showError(`upload ${file.name}: ${file.size} bytes; the limit is ${state.options.max_upload_bytes} bytes`); return; }
  const r = await api(`/api/upload?filename=${encodeURIComponent(file.name)}`, { method: "POST", body: file });
  if (!r.ok) { showError(r.data.error); return; }
  person().upload = r.data.pose;
  state.upload = r.data.pose;
  $("frame-row").hidden = !state.upload.endsWith(".bvh");
  if (await loadPose()) requestDesign();
}

async function main() {
  resize();
  const r = await api("/api/options");
  state.options = r.data;
  for (const p of r.data.poses) option($("pose-select"), p.name, p.supported ? p.name : `${p.name} (not supported)`);
  for (const b of r.data.bodies) option($("body-select"), b.name, b.name);
  for (const t of r.data.templates) option($("template-select"), t.name, t.name);
  $("template-select").value = r.data.default_template;
  state.people = [{ model: r.data.default_body, params: {}, pose: r.data.default_pose, upload: null, frame: 0, poseData: null, angles: null, made: null }];
  const templateParams = () => {
    const t = r.data.templates.find((x) => x.name === $("template-select").value);
    paramInputs($("template-params"), t.params, "template", null, () => requestDesign());
    const [lo, hi] = t.people || [1, 1];
    $("people-row").hidden = hi <= 1;
    $("people").min = lo; $("people").max = hi;
    $("people").value = Math.min(hi, Math.max(lo, Number($("people").value) || 1));
    setPeople(Number($("people").value));
  };
  buildSliders();
  templateParams();
  $("pose-select").addEventListener("change", async () => {
    const p = person();
    p.pose = $("pose-select").value; p.upload = null; state.upload = null;
    $("pose-upload").value = ""; $("frame-row").hidden = true;
    if (await loadPose()) requestDesign();
  });
  $("body-select").addEventListener("change", async () => {
    const p = person();
    p.model = $("body-select").value;
    p.params = {}; // the new model's own values, shown in its fields
    paramInputs($("body-params"), modelParams(p.model), "body", p.params, onBodyParams);
    showPeopleList();
    if (!p.upload || !p.upload.endsWith(".bvh") || await loadPose()) requestDesign();
  });
  $("person-select").addEventListener("change", () => { state.current = Number($("person-select").value); showPerson(); });
  $("template-select").addEventListener("change", () => { templateParams(); requestDesign(); });
  $("people").addEventListener("change", () => { setPeople(Math.max(1, Number($("people").value) || 1)); requestDesign(); });
  $("bvh-frame").addEventListener("change", async () => { person().frame = Number($("bvh-frame").value || 0); if (await loadPose()) requestDesign(); });
  $("pose-upload").addEventListener("change", onUpload);
  $("reset-joints").addEventListener("click", () => { person().angles = null; setSliders(); showPeopleList(); requestDesign(); });
  $("make-files").addEventListener("click", makeFiles);
  if (await loadPose()) requestDesign();
}

main();
