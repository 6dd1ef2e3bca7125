// 3D view of the as-new concave inner surface, faces coloured by remaining thickness (three.js).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { thicknessColor } from './util.js';

export class LinerView {
  constructor(container) {
    this.container = container;
    this.ok = false;
    try {
      this.renderer = new THREE.WebGLRenderer({ antialias: true, alpha: true, preserveDrawingBuffer: true });
      this.renderer.setClearColor(0x000000, 0);
    } catch (e) {
      container.append(Object.assign(document.createElement('div'), { className: 'empty', textContent: '3D view needs WebGL, which this browser does not offer.' }));
      return;
    }
    this.ok = true;
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.domElement.setAttribute('data-testid', 'liner-3d');
    container.append(this.renderer.domElement);
    const hint = document.createElement('div');
    hint.className = 'hint';
    hint.textContent = 'drag to orbit · scroll to zoom · right-drag to pan';
    container.append(hint);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 200);
    this.camera.up.set(0, 0, 1);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 1.5));
    const sun = new THREE.DirectionalLight(0xffffff, 0.9);
    sun.position.set(3, -4, 8);
    this.scene.add(sun);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = true;
    this.controls.addEventListener('change', () => this.requestRender());
    this.markers = new THREE.Group();
    this.scene.add(this.markers);
    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(container);
    this.mesh = null;
    this.meshSource = null;
  }

  destroy() {
    if (!this.ok) return;
    this.resizeObserver.disconnect();
    this.controls.dispose();
    this.renderer.dispose();
    cancelAnimationFrame(this.frame);
  }

  resize() {
    const w = this.container.clientWidth;
    const h = this.container.clientHeight;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender() {
    if (this.pending) return;
    this.pending = true;
    this.frame = requestAnimationFrame(() => {
      this.pending = false;
      // Damping keeps moving the camera for a while after the drag ends.
      if (this.controls.update()) this.requestRender();
      this.renderer.render(this.scene, this.camera);
    });
  }

  buildGeometry(meshData) {
    const { points, faces } = meshData;
    const n = faces.length / 3;
    const pos = new Float32Array(n * 9);
    for (let f = 0; f < n; f++) {
      for (let k = 0; k < 3; k++) {
        const i = faces[3 * f + k];
        pos[9 * f + 3 * k] = points[3 * i];
        pos[9 * f + 3 * k + 1] = points[3 * i + 1];
        pos[9 * f + 3 * k + 2] = points[3 * i + 2];
      }
    }
    const geom = new THREE.BufferGeometry();
    geom.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    geom.setAttribute('color', new THREE.BufferAttribute(new Float32Array(n * 9), 3));
    geom.computeVertexNormals();
    geom.computeBoundingSphere();
    geom.computeBoundingBox();
    const mat = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
    if (this.mesh) { this.scene.remove(this.mesh); this.mesh.geometry.dispose(); }
    this.mesh = new THREE.Mesh(geom, mat);
    this.scene.add(this.mesh);
    const bb = geom.boundingBox;
    const centre = new THREE.Vector3();
    bb.getCenter(centre);
    const r = geom.boundingSphere.radius;
    this.controls.target.copy(centre);
    // From above the feed side looking down into the bowl: the far inner wall faces the camera.
    this.camera.position.set(centre.x + r * 1.3, centre.y - r * 1.3, centre.z + r * 1.5);
    this.camera.near = r / 100;
    this.camera.far = r * 20;
    this.camera.updateProjectionMatrix();
    this.scale = r;
  }

  // state: same shape as UnwrappedMap.update
  update(state) {
    if (!this.ok) return;
    if (this.meshSource !== state.mesh) {
      this.buildGeometry(state.mesh);
      this.meshSource = state.mesh;
    }
    const col = this.mesh.geometry.getAttribute('color');
    const n = state.mesh.faces.length / 3;
    const lin = new THREE.Color();
    for (let f = 0; f < n; f++) {
      const c = thicknessColor(state.remaining ? state.remaining[f] : null, state.thicknessMin, state.thicknessNew);
      lin.setRGB(c[0] / 255, c[1] / 255, c[2] / 255, THREE.SRGBColorSpace); // the same colours as the map
      for (let k = 0; k < 3; k++) col.setXYZ(3 * f + k, lin.r, lin.g, lin.b);
    }
    col.needsUpdate = true;

    this.markers.clear();
    const radiusAt = (z) => this.radiusAt(state.mesh, z);
    const place = (thetaDeg, z, inset) => {
      const th = (thetaDeg * Math.PI) / 180;
      const rr = radiusAt(z) - inset;
      return new THREE.Vector3(rr * Math.cos(th), rr * Math.sin(th), z);
    };
    const sz = this.scale / 60;
    for (const sn of state.sensors) {
      const sel = sn.id === state.selected;
      const m = new THREE.Mesh(new THREE.SphereGeometry(sel ? sz * 1.6 : sz, 16, 12),
        new THREE.MeshBasicMaterial({ color: sel ? 0x111111 : 0xffffff }));
      m.position.copy(place(sn.theta_deg, sn.z_m, sz * 0.5));
      this.markers.add(m);
    }
    if (state.min && state.min.theta_deg != null) {
      const ring = new THREE.Mesh(new THREE.TorusGeometry(sz * 3, sz * 0.5, 8, 32), new THREE.MeshBasicMaterial({ color: 0x000000 }));
      const p = place(state.min.theta_deg, state.min.z_m, sz);
      ring.position.copy(p);
      ring.lookAt(new THREE.Vector3(0, 0, p.z));
      this.markers.add(ring);
    }
    this.requestRender();
  }

  // Mean radius of the mesh vertices near height z (the concave is a surface of revolution).
  radiusAt(mesh, z) {
    if (!this.radiusTable) this.radiusTable = new Map();
    let table = this.radiusTable.get(mesh);
    if (!table) {
      const pts = mesh.points;
      table = [];
      for (let i = 0; i < pts.length; i += 3) table.push([pts[i + 2], Math.hypot(pts[i], pts[i + 1])]);
      table.sort((a, b) => a[0] - b[0]);
      this.radiusTable.set(mesh, table);
    }
    let best = table[0];
    for (const row of table) if (Math.abs(row[0] - z) < Math.abs(best[0] - z)) best = row;
    return best[1];
  }
}
