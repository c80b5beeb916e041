// The organ and the instruments in the three.js scene: the deformed surface (shaded, with
// an optional wireframe and displacement colours), a hidden copy at rest for stable probe
// picking, the fixed vertices, the probe, grasper and scalpel, and the force arrow.
import * as THREE from 'three';
import { colormap, TISSUE_COLOUR } from './colormap.js';

export class Organ {
  constructor(scene) {
    this.scene = scene;
    this.group = new THREE.Group();
    scene.add(this.group);
    this.mesh = null;
    this.restMesh = null;
    this.wireframe = false;
    this.colours = false;
    this.showFixed = true;
    this.maxDisplacement = 0;
    this.colourScale = 0;
    this.size = 1;

    const mat = (c, extra = {}) => new THREE.MeshStandardMaterial({ color: c, roughness: 0.5, ...extra });
    this.probe = new THREE.Mesh(new THREE.SphereGeometry(1, 24, 16), mat(0xb0bec5, { metalness: 0.6 }));
    this.ghost = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0x90caf9, wireframe: true, transparent: true, opacity: 0.5 }));
    this.grasper = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0x81c784, wireframe: true }));
    this.blade = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]),
      new THREE.LineBasicMaterial({ color: 0xffffff }));
    this.arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 1, 0), new THREE.Vector3(), 1, 0xffb74d);
    this.cutLine = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xffeb3b }));
    for (const o of [this.probe, this.ghost, this.grasper, this.blade, this.arrow, this.cutLine]) {
      o.visible = false;
      scene.add(o);
    }
  }

  init(msg) {
    this.group.clear();
    this.size = msg.size;
    const rest = new Float32Array(msg.rest);
    this.rest = rest;
    const index = msg.triangles.length > 65535 ? new Uint32Array(msg.triangles) : new Uint16Array(msg.triangles);
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(rest.slice(), 3));
    geo.setAttribute('color', new THREE.BufferAttribute(new Float32Array(rest.length), 3));
    geo.setIndex(new THREE.BufferAttribute(index, 1));
    geo.computeVertexNormals();
    this.mesh = new THREE.Mesh(geo, new THREE.MeshStandardMaterial({
      vertexColors: true, roughness: 0.55, metalness: 0.0, side: THREE.DoubleSide,
    }));
    this.wire = new THREE.Mesh(geo, new THREE.MeshBasicMaterial({
      color: 0x111111, wireframe: true, transparent: true, opacity: 0.35,
    }));
    this.wire.visible = this.wireframe;
    const restGeo = new THREE.BufferGeometry();
    restGeo.setAttribute('position', new THREE.BufferAttribute(rest.slice(), 3));
    restGeo.setIndex(new THREE.BufferAttribute(index, 1));
    restGeo.computeVertexNormals();
    this.restMesh = new THREE.Mesh(restGeo, new THREE.MeshBasicMaterial({ side: THREE.DoubleSide }));
    this.restMesh.visible = false;
    const fixed = new Float32Array(msg.fixed.length * 3);
    msg.fixed.forEach((v, i) => fixed.set(rest.subarray(3 * v, 3 * v + 3), 3 * i));
    const fgeo = new THREE.BufferGeometry();
    fgeo.setAttribute('position', new THREE.BufferAttribute(fixed, 3));
    this.fixed = new THREE.Points(fgeo, new THREE.PointsMaterial({ color: 0x42a5f5, size: msg.size * 0.04 }));
    this.fixed.visible = this.showFixed;
    this.group.add(this.mesh, this.wire, this.restMesh, this.fixed);
    this.probe.scale.setScalar(msg.probe_radius);
    this.ghost.scale.setScalar(msg.probe_radius);
    this.colourScale = 0;
    this.maxDisplacement = 0;
    this.paint();
  }

  setWireframe(on) { this.wireframe = on; if (this.wire) this.wire.visible = on; }
  setColours(on) { this.colours = on; this.paint(); }
  setShowFixed(on) { this.showFixed = on; if (this.fixed) this.fixed.visible = on; }

  /// Per-vertex colours from the displacement (or the tissue colour).
  paint() {
    if (!this.mesh) return;
    const pos = this.mesh.geometry.attributes.position.array;
    const col = this.mesh.geometry.attributes.color.array;
    const rest = this.rest;
    let max = 0;
    const disp = new Float32Array(pos.length / 3);
    for (let i = 0; i < disp.length; i++) {
      const dx = pos[3 * i] - rest[3 * i], dy = pos[3 * i + 1] - rest[3 * i + 1], dz = pos[3 * i + 2] - rest[3 * i + 2];
      disp[i] = Math.sqrt(dx * dx + dy * dy + dz * dz);
      if (disp[i] > max) max = disp[i];
    }
    this.maxDisplacement = max;
    // The scale only grows (until reset) so colours do not flicker as the maximum moves.
    this.colourScale = Math.max(this.colourScale, max, 1e-3 * this.size);
    for (let i = 0; i < disp.length; i++) {
      if (this.colours) colormap(disp[i] / this.colourScale, col, 3 * i);
      else col.set(TISSUE_COLOUR, 3 * i);
    }
    this.mesh.geometry.attributes.color.needsUpdate = true;
  }

  frame(msg) {
    if (!this.mesh) return;
    const attr = this.mesh.geometry.attributes.position;
    if (msg.positions.length !== attr.array.length) return; // a new init is on its way
    attr.array.set(msg.positions);
    attr.needsUpdate = true;
    this.mesh.geometry.computeVertexNormals();
    this.mesh.geometry.computeBoundingSphere();
    this.paint();
    const v = (a) => new THREE.Vector3(a[0], a[1], a[2]);
    this.probe.visible = !!(msg.probe && msg.probe_active);
    if (this.probe.visible) this.probe.position.copy(v(msg.probe.position));
    this.grasper.visible = !!msg.grasper;
    if (msg.grasper) {
      this.grasper.position.copy(v(msg.grasper.position));
      this.grasper.scale.setScalar(msg.grasper.radius);
    }
    this.blade.visible = !!(msg.scalpel && msg.scalpel.blade);
    if (this.blade.visible) this.blade.geometry.setFromPoints(msg.scalpel.blade.map(v));
    // The force on the active tool, drawn at its tip.
    const tool = msg.grasper ? msg.grasper : (msg.probe_active ? msg.probe : null);
    const f = msg.grasper ? v(msg.grasper.force) : v(msg.haptic_force);
    const n = f.length();
    this.arrow.visible = !!tool && n > 1e-9;
    if (this.arrow.visible) {
      this.arrow.position.copy(v(tool.position));
      this.arrow.setDirection(f.clone().divideScalar(n));
      const len = this.size * 0.8 * n / (n + 0.1);
      this.arrow.setLength(len, len * 0.25, len * 0.12);
    }
    return n;
  }

  showCutPath(points) {
    this.cutLine.geometry.setFromPoints(points);
    this.cutLine.visible = points.length > 1;
  }
}
