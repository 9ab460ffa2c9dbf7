// The 3-D lobe surface (three.js, vendored): critical depth over spindle speed × allowance,
// coloured by depth, with each allowance's lobe curve drawn on it. The axes are scaled to a
// unit box (rpm spans thousands, allowance a few mm); the page's caption gives the ranges.
import * as THREE from 'three';
import { OrbitControls } from '/ui/OrbitControls.js';

// grid[a][r]: depth at allowances[a], rpms[r] (null where not computed).
export function showLobeSurface(container, rpms, allowances, grid) {
  const width = Math.max(320, container.clientWidth);
  const height = 420;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(width, height);
  renderer.setClearColor(0xf4f6f9);
  container.append(renderer.domElement);

  let maxDepth = 0;
  for (const row of grid) for (const d of row) if (d !== null && d > maxDepth) maxDepth = d;
  const r0 = rpms[0]; const r1 = rpms[rpms.length - 1];
  const a0 = allowances[0]; const a1 = allowances[allowances.length - 1];
  const X = (r) => (r1 > r0 ? (r - r0) / (r1 - r0) : 0) * 2 - 1;
  const Y = (a) => (a1 > a0 ? (a - a0) / (a1 - a0) : 0) * 1.2 - 0.6;
  const Z = (d) => (maxDepth > 0 ? d / maxDepth : 0) * 0.9;

  const nr = rpms.length; const na = allowances.length;
  const pos = new Float32Array(nr * na * 3);
  const col = new Float32Array(nr * na * 3);
  const c = new THREE.Color();
  for (let a = 0; a < na; a++) {
    for (let r = 0; r < nr; r++) {
      const k = (a * nr + r) * 3;
      const d = grid[a][r] ?? 0;
      pos[k] = X(rpms[r]); pos[k + 1] = Y(allowances[a]); pos[k + 2] = Z(d);
      // Blue (shallow, unstable early) to red (deep, stable pockets).
      c.setHSL(0.66 * (1 - (maxDepth > 0 ? d / maxDepth : 0)), 0.75, 0.5);
      col[k] = c.r; col[k + 1] = c.g; col[k + 2] = c.b;
    }
  }
  const index = [];
  for (let a = 0; a + 1 < na; a++) {
    for (let r = 0; r + 1 < nr; r++) {
      const i = a * nr + r;
      index.push(i, i + 1, i + nr, i + 1, i + nr + 1, i + nr);
    }
  }
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  geom.setAttribute('color', new THREE.BufferAttribute(col, 3));
  geom.setIndex(index);
  geom.computeVertexNormals();
  const scene = new THREE.Scene();
  scene.add(new THREE.Mesh(geom, new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide })));
  // Each allowance's lobe curve, dark, just above the surface.
  for (let a = 0; a < na; a++) {
    const pts = [];
    for (let r = 0; r < nr; r++) pts.push(new THREE.Vector3(X(rpms[r]), Y(allowances[a]), Z(grid[a][r] ?? 0) + 0.003));
    scene.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(pts), new THREE.LineBasicMaterial({ color: 0x1d2430 })));
  }
  // The floor's box: rpm along x, allowance along y.
  const floor = new THREE.BufferGeometry().setFromPoints([[-1, -0.6], [1, -0.6], [1, 0.6], [-1, 0.6], [-1, -0.6]].map(([x, y]) => new THREE.Vector3(x, y, 0)));
  scene.add(new THREE.Line(floor, new THREE.LineBasicMaterial({ color: 0x888888 })));
  scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.2);
  sun.position.set(-1, -2, 3);
  scene.add(sun);

  const camera = new THREE.PerspectiveCamera(35, width / height, 0.01, 50);
  camera.up.set(0, 0, 1);
  camera.position.set(1.4, -3.0, 2.0);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(0, 0, 0.3);
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);
  controls.update();
  render();
  return { maxDepth, vertices: nr * na };
}
