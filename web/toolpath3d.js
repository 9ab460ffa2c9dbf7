// An interpreted program's tool path in 3-D (three.js, vendored): rapids orange, feed moves
// blue, arcs drawn through their centre (helices included). Orbit, zoom and pan.
import * as THREE from 'three';
import { OrbitControls } from '/ui/OrbitControls.js';

const RAPID = new THREE.Color(0xef6c00);
const FEED = new THREE.Color(0x2463eb);
const MARK = new THREE.Color(0xd81b60);

// Points along an arc from p to q about centre c with unit normal n (clockwise seen from +n).
function arcPoints(p, q, c, n, clockwise) {
  const u = p.clone().sub(c);
  const h0 = u.dot(n);
  u.addScaledVector(n, -h0);
  const v = q.clone().sub(c);
  const h1 = v.dot(n);
  v.addScaledVector(n, -h1);
  const r = u.length();
  if (!(r > 1e-9)) return [q];
  let sweep = Math.atan2(n.dot(u.clone().cross(v)), u.dot(v)); // counter-clockwise angle
  if (clockwise) { if (sweep >= 0) sweep -= 2 * Math.PI; } else if (sweep <= 0) sweep += 2 * Math.PI;
  // A full circle has equal ends: the sweep above is then ±2π.
  const steps = Math.max(4, Math.ceil(Math.abs(sweep) / (Math.PI / 36)));
  const w = n.clone().cross(u); // u rotated +90° about n
  const rv = v.length() / r; // end radius / start radius: spirals change it linearly
  const out = [];
  for (let k = 1; k <= steps; k++) {
    const a = (sweep * k) / steps;
    const s = 1 + (rv - 1) * (k / steps);
    out.push(c.clone().addScaledVector(u, Math.cos(a) * s).addScaledVector(w, Math.sin(a) * s).addScaledVector(n, h0 + ((h1 - h0) * k) / steps));
  }
  return out;
}

// rows: the interpret job's Rows (end_x/y/z, kind, center_x/y/z, normal_x/y/z, clockwise).
export function showToolpath(container, rows) {
  const width = Math.max(320, container.clientWidth);
  const height = 480;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(width, height);
  renderer.setClearColor(0xf4f6f9);
  container.append(renderer.domElement);

  const ex = rows.col('end_x'); const ey = rows.col('end_y'); const ez = rows.col('end_z');
  const kind = rows.col('kind');
  const cx = rows.col('center_x'); const cy = rows.col('center_y'); const cz = rows.col('center_z');
  const nx = rows.col('normal_x'); const ny = rows.col('normal_y'); const nz = rows.col('normal_z');
  const cw = rows.col('clockwise');
  const pos = []; const col = [];
  let prev = null;
  const seg = (a, b, c) => { pos.push(a.x, a.y, a.z, b.x, b.y, b.z); col.push(c.r, c.g, c.b, c.r, c.g, c.b); };
  for (let i = 0; i < rows.length; i++) {
    if (ex[i] === null || ey[i] === null || ez[i] === null) continue;
    const q = new THREE.Vector3(ex[i], ey[i], ez[i]);
    if (prev && !q.equals(prev)) {
      const c = kind[i] === 'rapid' ? RAPID : kind[i] === 'linear' || kind[i] === 'arc' ? FEED : MARK;
      if (kind[i] === 'arc' && cx[i] !== null && nx[i] !== null) {
        let a = prev;
        for (const b of arcPoints(prev, q, new THREE.Vector3(cx[i], cy[i], cz[i]), new THREE.Vector3(nx[i], ny[i], nz[i]).normalize(), cw[i] === 'true')) { seg(a, b, c); a = b; }
      } else seg(prev, q, c);
    }
    prev = q;
  }
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  geom.setAttribute('color', new THREE.Float32BufferAttribute(col, 3));
  geom.computeBoundingBox();
  const scene = new THREE.Scene();
  scene.add(new THREE.LineSegments(geom, new THREE.LineBasicMaterial({ vertexColors: true })));
  const box = geom.boundingBox;
  const centre = box.getCenter(new THREE.Vector3());
  const size = Math.max(1e-3, box.getSize(new THREE.Vector3()).length());
  scene.add(new THREE.AxesHelper(size * 0.15));
  const camera = new THREE.PerspectiveCamera(35, width / height, size / 1000, size * 20);
  camera.up.set(0, 0, 1);
  camera.position.copy(centre).add(new THREE.Vector3(0.9, -1.3, 1.0).multiplyScalar(size * 0.9));
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(centre);
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);
  controls.update();
  render();
  const dims = box.getSize(new THREE.Vector3());
  return { segments: pos.length / 6, size: [dims.x, dims.y, dims.z] };
}
