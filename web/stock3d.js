// The machined stock in 3-D (three.js, vendored): the job's exported STL, and the design
// part as a translucent overlay where the job has one, and collisions and gouges marked
// where the summary places them. Orbit, zoom and pan with the mouse.
import * as THREE from 'three';
import { STLLoader } from '/ui/STLLoader.js';
import { OrbitControls } from '/ui/OrbitControls.js';

// gouges: the summary's part.gouges (at, min, max in the part frame, mm).
export function showStock(container, stockStl, partStl, marks, gouges) {
  const width = Math.max(320, container.clientWidth);
  const height = 480;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(width, height);
  renderer.setClearColor(0xf4f6f9);
  container.append(renderer.domElement);

  const scene = new THREE.Scene();
  const loader = new STLLoader();
  const stock = loader.parse(stockStl);
  stock.computeVertexNormals();
  stock.computeBoundingBox();
  const mesh = new THREE.Mesh(stock, new THREE.MeshStandardMaterial({ color: 0x9aa7b8, metalness: 0.35, roughness: 0.45 }));
  scene.add(mesh);
  let part = null;
  if (partStl) {
    const g = loader.parse(partStl);
    g.computeVertexNormals();
    part = new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color: 0x2e7d32, transparent: true, opacity: 0.35, depthWrite: false }));
    scene.add(part);
  }
  // Collisions: the move's tip path in red with a ball at its middle, drawn over the stock
  // (no depth test: a rapid through material is inside it) and sized to the stock.
  const box0 = stock.boundingBox;
  const radius = Math.max(0.5, box0.getSize(new THREE.Vector3()).length() / 120);
  const ball = new THREE.SphereGeometry(radius, 16, 12);
  const red = new THREE.MeshBasicMaterial({ color: 0xd50000, depthTest: false, transparent: true, opacity: 0.85 });
  const redLine = new THREE.LineBasicMaterial({ color: 0xd50000, depthTest: false });
  for (const m of marks || []) {
    const a = new THREE.Vector3(...m.from); const b = new THREE.Vector3(...m.to);
    const s = new THREE.Mesh(ball, red);
    s.position.copy(a).lerp(b, 0.5);
    s.renderOrder = 2;
    const l = new THREE.Line(new THREE.BufferGeometry().setFromPoints([a, b]), redLine);
    l.renderOrder = 2;
    scene.add(s, l);
  }
  // Gouges: the region's box in magenta with a ball at its deepest point, drawn over the
  // stock and the part (a gouge lies under the part's surface).
  const magenta = new THREE.MeshBasicMaterial({ color: 0xd500f9, depthTest: false, transparent: true, opacity: 0.9 });
  const magentaLine = new THREE.LineBasicMaterial({ color: 0xd500f9, depthTest: false });
  for (const g of gouges || []) {
    const s = new THREE.Mesh(ball, magenta);
    s.position.set(...g.at);
    s.renderOrder = 3;
    const box = new THREE.Box3(new THREE.Vector3(...g.min), new THREE.Vector3(...g.max));
    const h = new THREE.Box3Helper(box, 0xd500f9);
    h.material = magentaLine;
    h.renderOrder = 3;
    scene.add(s, h);
  }
  scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(1, -1.5, 2);
  scene.add(sun);

  // The part frame has Z up; look at the stock's box from the front-right, above.
  const box = stock.boundingBox;
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
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
  return {
    triangles: stock.attributes.position.count / 3,
    size: [dims.x, dims.y, dims.z],
    setPartVisible(v) { if (part) { part.visible = v; render(); } },
  };
}
