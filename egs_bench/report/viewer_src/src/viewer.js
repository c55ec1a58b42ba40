// The report's 3D view: a run's Gaussian map (Spark), its trajectories and keyframe frusta
// (three.js lines), orbit / fly controls and a frame slider; and the sequence page's scene of
// all methods' trajectories. Built by build.sh into one classic script (../static/viewer.js)
// that exposes window.EgsViewer; each page's data comes from a classic <script> that sets
// window.EGS_VIEW (a page opened from file:// may not fetch files or load ES modules).
//
// Conventions (docs/design.md §2): poses are camera-to-world 4x4 matrices, row-major in the
// data, with OpenCV camera axes (x right, y down, z forward); pixel u covers [u, u + 1) and a
// camera point projects to u = fx X / Z + cx.

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { PackedSplats, SparkControls, SparkRenderer, SplatMesh, setPackedSplat } from "@sparkjsdev/spark";

// OpenCV camera axes -> three.js camera axes (y up, looking down -z)
const CV_TO_GL = new THREE.Matrix4().makeScale(1, -1, -1);
// Spark's splat texture width (PackedSplats drops a partial last row of it)
const SPLAT_TEX_WIDTH = 2048;
const EST_COLOR = 0xe4572e;
const GT_COLOR = 0x2a9d8f;
const FRUSTUM_COLOR = 0xf2c14e;
const PALETTE = [0xe4572e, 0x4c78a8, 0x9c27b0, 0xf58518, 0x54a24b, 0xb279a2, 0x72b7b2,
  0xeeca3b, 0xff9da6, 0x9d755d];

function decodeBase64(text) {
  const bin = atob(text);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

function poseMatrix(rowMajor) {
  const m = new THREE.Matrix4();
  m.set(...rowMajor);
  return m;
}

// The quantised map (see egs_bench/report/viewer.py, encode_splats): struct of arrays, little
// endian: positions uint16 [n, 3] over the bounding box, log scales uint8 [n, 3] over
// [ln_scale_min, ln_scale_max], display colours uint8 [n, 3] over [color_min, color_max] per
// channel, opacities uint8 [n], unit quaternions (w, x, y, z) int8 [n, 4] / 127.
// Returns Spark's packed splats (16 bytes each: float16 centres relative to `origin`, 8-bit
// colour and log scales over this map's ranges, octahedral quaternions) and that origin.
function packSplats(map) {
  const bytes = decodeBase64(map.data);
  const n = map.count;
  const view = new DataView(bytes.buffer);
  const scaleOff = 6 * n, colOff = 9 * n, opOff = 12 * n, rotOff = 13 * n;
  const lo = map.bbox_min, hi = map.bbox_max;
  const c0 = map.color_min, c1 = map.color_max;
  const s0 = map.ln_scale_min, s1 = map.ln_scale_max;
  const encoding = {
    rgbMin: Math.min(0, ...c0), rgbMax: Math.max(1, ...c1),
    lnScaleMin: s0 - 1e-3, lnScaleMax: s1 + 1e-3,
  };
  // float16 centres are finest near 0: store them relative to the box centre
  const origin = [0, 1, 2].map((k) => 0.5 * (lo[k] + hi[k]));
  // whole texture rows: Spark ignores the splats of a last, partial row
  const packed = new Uint32Array(4 * Math.ceil(n / SPLAT_TEX_WIDTH) * SPLAT_TEX_WIDTH);
  const q = new Float64Array(4);
  for (let i = 0; i < n; i++) {
    const p = (k) => lo[k] + (hi[k] - lo[k]) * view.getUint16(2 * (3 * i + k), true) / 65535 - origin[k];
    const s = (k) => Math.exp(s0 + (s1 - s0) * bytes[scaleOff + 3 * i + k] / 255);
    const c = (k) => c0[k] + (c1[k] - c0[k]) * bytes[colOff + 3 * i + k] / 255;
    for (let k = 0; k < 4; k++) q[k] = view.getInt8(rotOff + 4 * i + k) / 127;
    const norm = Math.hypot(q[0], q[1], q[2], q[3]) || 1;
    setPackedSplat(packed, i, p(0), p(1), p(2), s(0), s(1), s(2),
      q[1] / norm, q[2] / norm, q[3] / norm, q[0] / norm, bytes[opOff + i] / 255,
      c(0), c(1), c(2), encoding);
  }
  return { packedSplats: new PackedSplats({ packedArray: packed, numSplats: n, splatEncoding: encoding }), encoding, origin };
}

function polyline(points, color) {
  const geom = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
  const line = new THREE.Line(geom, new THREE.LineBasicMaterial({ color }));
  return line;
}

// A camera frustum drawn as 8 line segments, at depth `depth` (m), in the camera's frame
function frustum(camera, pose, depth, color) {
  const { width: w, height: h, fx, fy, cx, cy } = camera;
  const corner = (u, v) => new THREE.Vector3((u - cx) / fx * depth, (v - cy) / fy * depth, depth);
  const c = [corner(0, 0), corner(w, 0), corner(w, h), corner(0, h)];
  const o = new THREE.Vector3();
  const pts = [o, c[0], o, c[1], o, c[2], o, c[3], c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0]];
  const geom = new THREE.BufferGeometry().setFromPoints(pts);
  const seg = new THREE.LineSegments(geom, new THREE.LineBasicMaterial({ color }));
  seg.matrixAutoUpdate = false;
  seg.matrix.copy(poseMatrix(pose));
  return seg;
}

// The projection of a pinhole camera K at size (w, h), in three.js clip space (y up)
function projection(camera, near, far, flipY) {
  const { width: w, height: h, fx, fy, cx, cy } = camera;
  const sy = flipY ? -1 : 1;
  const m = new THREE.Matrix4();
  m.set(2 * fx / w, 0, 1 - 2 * cx / w, 0,
    0, sy * 2 * fy / h, sy * (2 * cy / h - 1), 0,
    0, 0, -(far + near) / (far - near), -2 * far * near / (far - near),
    0, 0, -1, 0);
  return m;
}

function sceneRadius(points) {
  const box = new THREE.Box3();
  for (const p of points) box.expandByPoint(new THREE.Vector3(...p));
  const size = box.getSize(new THREE.Vector3()).length();
  return { center: box.getCenter(new THREE.Vector3()), radius: Math.max(size / 2, 0.1) };
}

class Base3D {
  constructor(canvas, width, height) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.renderer.setClearColor(0x000000, 1);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(60, width / height, 0.01, 1000);
    this.setSize(width, height);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener("change", () => this.requestRender());
    this.pending = false;
  }

  setSize(width, height) {
    this.width = width;
    this.height = height;
    this.renderer.setSize(width, height, true);
  }

  requestRender() {
    this.changedAt = performance.now();
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => { this.pending = false; this.renderNow(); });
  }

  renderNow() {
    this.renderer.render(this.scene, this.camera);
  }
}

class RunView extends Base3D {
  constructor(root, data) {
    const cam = data.camera;
    const canvas = root.querySelector("canvas.egs-view-canvas");
    super(canvas, cam.width, cam.height);
    this.root = root;
    this.data = data;
    this.scale = 1;
    this.flipY = false;
    this.mode = "orbit";
    this.frame = 0;
    this.sceneCounts = { trajectories: 0, frusta: 0, splats: 0 };
    this.spark = new SparkRenderer({
      renderer: this.renderer,
      onDirty: () => this.requestRender(),
      // as the toolkit's rasteriser (docs/design.md §5): a 0.3 px^2 blur without opacity
      // compensation, 3-sigma extent, alpha below 1/255 skipped, depth sort along the view axis
      preBlurAmount: 0.3, blurAmount: 0.0, maxStdDev: 3.0, minAlpha: 1.0 / 255.0,
      sortRadial: false, clipXY: 1.3,
    });
    this.scene.add(this.spark);
    this.build();
    this.flyControls = new SparkControls({ canvas });
    this.flyControls.fpsMovement.enable = false;
    this.flyControls.pointerControls.enable = false;
    this.lastTime = performance.now();
    this.bindUi();
    this.setScale(Math.max(1, Math.min(4, Math.floor(720 / cam.width))));
    this.setFrame(0);
    this.loop();
  }

  build() {
    const d = this.data;
    this.group = new THREE.Group();
    this.scene.add(this.group);
    if (d.map) {
      // Spark's 16-byte packed splats (three 0.187 cannot upload its 32-byte extended
      // splats: texSubImage3D fails)
      const { packedSplats, encoding, origin } = packSplats(d.map);
      this.splats = new SplatMesh({ packedSplats, splatEncoding: encoding });
      this.splats.position.set(...origin);
      this.splats.initialized.then(() => { this.ready = true; this.requestRender(); });
      this.scene.add(this.splats);
      this.sceneCounts.splats = d.map.count;
    } else {
      this.ready = true;
    }
    this.lines = {};
    if (d.est && d.est.length) {
      this.lines.est = polyline(d.est, EST_COLOR);
      this.group.add(this.lines.est);
      this.sceneCounts.trajectories++;
    }
    if (d.gt && d.gt.length) {
      this.lines.gt = polyline(d.gt, GT_COLOR);
      this.group.add(this.lines.gt);
      this.sceneCounts.trajectories++;
    }
    const pts = [...(d.est || []), ...(d.gt || [])];
    const { center } = sceneRadius(pts.length ? pts : [[0, 0, 0]]);
    // frusta and the orbit distance at the scale of the scene: the map's extent when there is
    // one (a short trajectory would make them invisible), else the trajectories'
    let { radius } = sceneRadius(pts.length ? pts : [[0, 0, 0]]);
    if (d.map && d.map.count) {
      radius = Math.max(radius, 0.25 * sceneRadius([d.map.bbox_min, d.map.bbox_max]).radius);
    }
    this.frusta = new THREE.Group();
    for (const k of d.keyframes) {
      const f = d.frames[k];
      if (f) this.frusta.add(frustum(d.camera, f.pose, 0.08 * radius, FRUSTUM_COLOR));
    }
    this.group.add(this.frusta);
    this.sceneCounts.frusta = this.frusta.children.length;
    this.current = frustum(d.camera, d.frames[0].pose, 0.12 * radius, 0xffffff);
    this.group.add(this.current);
    this.orbitCenter = center;
    this.orbitRadius = radius;
    // orbit about the first camera's up direction (its -y axis, OpenCV axes)
    const p0 = d.frames[0].pose;
    this.camera.up.set(-p0[1], -p0[5], -p0[9]).normalize();
  }

  bindUi() {
    const q = (s) => this.root.querySelector(s);
    this.slider = q("input.egs-view-frame");
    this.slider.max = String(this.data.frames.length - 1);
    this.slider.addEventListener("input", () => this.setFrame(Number(this.slider.value)));
    q("button.egs-view-orbit").addEventListener("click", () => this.setMode("orbit"));
    q("button.egs-view-fly").addEventListener("click", () => this.setMode("fly"));
    q("select.egs-view-scale").addEventListener("change", (e) => this.setScale(Number(e.target.value)));
    for (const box of this.root.querySelectorAll("input.egs-view-toggle")) {
      box.addEventListener("change", () => {
        const what = box.dataset.what;
        const obj = what === "map" ? this.splats : what === "frusta" ? this.frusta : this.lines[what];
        if (obj) obj.visible = box.checked;
        this.requestRender();
      });
    }
    const cmp = q("input.egs-view-compare");
    if (cmp) cmp.addEventListener("input", () => this.setCompare(Number(cmp.value)));
  }

  setScale(scale) {
    this.scale = scale;
    const sel = this.root.querySelector("select.egs-view-scale");
    if (sel) sel.value = String(scale);
    const c = this.data.camera;
    this.setSize(c.width * scale, c.height * scale);
    this.applyProjection();
    this.requestRender();
  }

  scaledCamera() {
    const c = this.data.camera, s = this.scale;
    return { width: c.width * s, height: c.height * s, fx: c.fx * s, fy: c.fy * s, cx: c.cx * s, cy: c.cy * s };
  }

  applyProjection() {
    const near = this.data.camera.near || 0.01;
    this.camera.near = near;
    this.camera.far = 1000;
    this.camera.projectionMatrix.copy(projection(this.scaledCamera(), near, 1000, this.flipY));
    this.camera.projectionMatrixInverse.copy(this.camera.projectionMatrix).invert();
  }

  // Puts the camera at frame i's estimated pose with the run's intrinsics
  setFrame(i) {
    const f = this.data.frames[i];
    this.frame = i;
    this.slider.value = String(i);
    const m = poseMatrix(f.pose).multiply(CV_TO_GL);
    m.decompose(this.camera.position, this.camera.quaternion, new THREE.Vector3());
    this.camera.updateMatrixWorld(true);
    this.current.matrix.copy(poseMatrix(f.pose));
    this.current.visible = false;  // the view is this camera's own
    // orbit around a point in front of the camera, at the scene's scale
    const ahead = new THREE.Vector3(0, 0, -this.orbitRadius).applyQuaternion(this.camera.quaternion);
    this.controls.target.copy(this.camera.position).add(ahead);
    this.controls.update();
    m.decompose(this.camera.position, this.camera.quaternion, new THREE.Vector3());
    this.camera.updateMatrixWorld(true);
    this.applyProjection();
    this.showImages(i);
    this.root.dataset.frame = String(f.index);
    const label = this.root.querySelector(".egs-view-frame-label");
    if (label) label.textContent = `frame ${f.index} (${i + 1} of ${this.data.frames.length})`;
    this.requestRender();
  }

  setMode(mode) {
    this.mode = mode;
    this.controls.enabled = mode === "orbit";
    this.flyControls.fpsMovement.enable = mode === "fly";
    this.flyControls.pointerControls.enable = mode === "fly";
    if (mode === "orbit") {
      const ahead = new THREE.Vector3(0, 0, -this.orbitRadius).applyQuaternion(this.camera.quaternion);
      this.controls.target.copy(this.camera.position).add(ahead);
      this.controls.update();
    }
    for (const b of this.root.querySelectorAll("button.egs-view-orbit, button.egs-view-fly")) {
      b.classList.toggle("active", b.classList.contains(`egs-view-${mode}`));
    }
    this.current.visible = true;
  }

  showImages(i) {
    const f = this.data.frames[i];
    const panel = this.root.querySelector(".egs-view-images");
    if (!panel) return;
    const img = this.data.frames[f.images_from] || f;
    const set = (cls, src) => {
      const el = panel.querySelector(cls);
      if (!el) return;
      el.hidden = !src;
      if (src) el.src = this.data.root + src;
      else el.removeAttribute("src");
    };
    set("img.egs-view-observed", img.observed);
    set("img.egs-view-render", img.render);
    set("img.egs-view-sharp", img.sharp);
    set("img.egs-view-cmp-render", img.render);
    set("img.egs-view-cmp-sharp", img.sharp || img.observed);
    const label = panel.querySelector(".egs-view-image-frame");
    label.textContent = img === f ? `frame ${f.index}` :
      `frame ${img.index} (the nearest frame with stored images; the view is at frame ${f.index})`;
    panel.dataset.frame = String(img.index);
  }

  setCompare(percent) {
    const top = this.root.querySelector(".egs-view-cmp-top");
    if (top) top.style.clipPath = `inset(0 ${100 - percent}% 0 0)`;
  }

  loop() {
    requestAnimationFrame(() => this.loop());
    const now = performance.now();
    const dt = Math.min(0.1, (now - this.lastTime) / 1000);
    this.lastTime = now;
    if (this.mode === "fly") {
      const before = this.camera.matrixWorld.clone();
      this.flyControls.update(this.camera);
      this.camera.updateMatrixWorld(true);
      if (!before.equals(this.camera.matrixWorld)) this.requestRender();
    }
    void dt;
  }

  // Test and automation hooks --------------------------------------------------------------
  // Whether the map is built and the sort for the current camera has finished
  settled() {
    // quiet for a few frames: a render after a camera change starts the sort it then waits for
    const quiet = performance.now() - (this.changedAt || 0) > 250;
    return Boolean(this.ready) && quiet && !this.spark.sorting && !this.spark.sortDirty &&
      !this.pending;
  }

  // The canvas as a PNG data URL, rendered now
  capture() {
    this.renderNow();
    return this.canvas.toDataURL("image/png");
  }

  // A deliberate convention error (for the browser test: the check must catch it)
  setPlantedError(kind) {
    this.flipY = kind === "flip-y";
    this.applyProjection();
    this.requestRender();
  }
}

class SequenceView extends Base3D {
  constructor(root, data) {
    const canvas = root.querySelector("canvas.egs-view-canvas");
    super(canvas, Math.min(960, root.clientWidth || 960), 540);
    this.data = data;
    this.lines = [];
    const all = [];
    data.runs.forEach((run, k) => {
      const color = PALETTE[k % PALETTE.length];
      const swatch = root.querySelector(`span.swatch[data-run="${k}"]`);
      if (swatch) swatch.style.background = `#${color.toString(16).padStart(6, "0")}`;
      const group = new THREE.Group();
      if (run.est && run.est.length) group.add(polyline(run.est, color));
      this.lines.push(group);
      this.scene.add(group);
      all.push(...(run.est || []));
    });
    if (data.gt && data.gt.length) {
      this.gt = polyline(data.gt, 0xffffff);
      this.scene.add(this.gt);
      all.push(...data.gt);
    }
    const { center, radius } = sceneRadius(all.length ? all : [[0, 0, 0]]);
    this.camera.position.copy(center).add(new THREE.Vector3(0, -0.8 * radius, -1.1 * radius));
    this.camera.up.set(0, -1, 0);
    this.controls.target.copy(center);
    this.controls.update();
    for (const box of root.querySelectorAll("input.egs-view-toggle")) {
      box.addEventListener("change", () => {
        const k = box.dataset.run;
        const obj = k === "gt" ? this.gt : this.lines[Number(k)];
        if (obj) obj.visible = box.checked;
        this.requestRender();
      });
    }
    this.sceneCounts = { trajectories: this.lines.filter((g) => g.children.length).length + (this.gt ? 1 : 0) };
    this.requestRender();
  }

  settled() {
    return !this.pending && performance.now() - (this.changedAt || 0) > 250;
  }
}

const views = [];

function init() {
  const data = window.EGS_VIEW;
  const root = document.querySelector(".egs-view");
  if (!data || !root) return;
  try {
    views.push(data.kind === "sequence" ? new SequenceView(root, data) : new RunView(root, data));
  } catch (err) {
    const note = root.querySelector(".egs-view-note");
    if (note) note.textContent = `The 3D view could not start: ${err.message}`;
    throw err;
  }
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", init);
} else {
  init();
}

window.EgsViewer = { views };
