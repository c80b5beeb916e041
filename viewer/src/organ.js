// The organ and the instruments in the three.js scene: the deformed surface (shaded, with
// an optional wireframe and displacement colours), a hidden copy at rest for stable probe
// picking, the fixed vertices, the probe, grasper and scalpel, and the force arrow.
import * as THREE from 'three';
import { colormap, TISSUE_COLOUR } from './colormap.js';

const CUT_COLOUR = [0.05, 0.004, 0.003];
// A composed model's parts (hybrid): the pre-computed rest in the tissue colour, the cuttable
// region lighter and yellower, its border orange.
const PART_COLOURS = [TISSUE_COLOUR, [0.85, 0.32, 0.04], [0.62, 0.3, 0.1]];

// A round, soft-edged dot for the fixed-vertex markers (square points look like noise).
function dotTexture() {
  const c = document.createElement('canvas');
  c.width = c.height = 64;
  const g = c.getContext('2d');
  const grad = g.createRadialGradient(32, 32, 0, 32, 32, 31);
  grad.addColorStop(0, 'rgba(255,255,255,1)');
  grad.addColorStop(0.6, 'rgba(255,255,255,1)');
  grad.addColorStop(0.8, 'rgba(40,60,90,1)');
  grad.addColorStop(1, 'rgba(40,60,90,0)');
  g.fillStyle = grad;
  g.fillRect(0, 0, 64, 64);
  const t = new THREE.CanvasTexture(c);
  t.colorSpace = THREE.SRGBColorSpace;
  return t;
}

// A line whose geometry is replaced, not resized: three.js keeps a buffer's size once it
// is drawn, and `setFromPoints` with more points warns "Buffer size too small".
function setLine(line, points) {
  line.geometry.dispose();
  line.geometry = new THREE.BufferGeometry().setFromPoints(points);
}

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
    // What the colours show: 'displacement' (m) or 'strain' (the frames' per-vertex
    // equivalent strain, for models with tetrahedra).
    this.quantity = 'displacement';
    this.strain = null;
    this.strainScale = 0;
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
    // The scalpel path while it is drawn: on top of the organ, never hidden by it.
    this.cutLine = new THREE.Line(new THREE.BufferGeometry(),
      new THREE.LineBasicMaterial({ color: 0xffeb3b, depthTest: false, transparent: true, toneMapped: false }));
    this.cutLine.renderOrder = 10;
    this.cutDots = new THREE.Points(new THREE.BufferGeometry(),
      new THREE.PointsMaterial({ color: 0xffeb3b, size: 6, sizeAttenuation: false, depthTest: false, transparent: true, toneMapped: false }));
    this.cutDots.renderOrder = 10;
    this.dot = dotTexture();
    for (const o of [this.probe, this.ghost, this.grasper, this.blade, this.arrow, this.cutLine, this.cutDots]) {
      o.visible = false;
      scene.add(o);
    }
  }

  init(msg) {
    this.group.clear();
    this.size = msg.size;
    this.labels = null;
    // A voxel organ's surface is made of cube faces: it is drawn smoothed (Taubin's
    // shrink-free filter, a few passes over the neighbours; the mechanics are untouched).
    this.smoother = msg.smooth ? new Smoother(msg.triangles, msg.rest.length / 3) : null;
    const rest = new Float32Array(msg.rest);
    if (this.smoother) this.smoother.apply(rest);
    this.rest = rest;
    const index = msg.triangles.length > 65535 ? new Uint32Array(msg.triangles) : new Uint16Array(msg.triangles);
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(rest.slice(), 3));
    geo.setAttribute('color', new THREE.BufferAttribute(new Float32Array(rest.length), 3));
    geo.setIndex(new THREE.BufferAttribute(index, 1));
    geo.computeVertexNormals();
    // Wet soft tissue: physically based, fairly smooth (a moist surface's highlights),
    // non-metallic; smooth (per-vertex, shared) normals. MeshPhysicalMaterial's clear coat
    // and sheen looked a little better but cost 3-5x the frame time in software WebGL.
    this.mesh = new THREE.Mesh(geo, new THREE.MeshStandardMaterial({
      vertexColors: true, roughness: 0.42, metalness: 0.0, side: THREE.DoubleSide,
      // Pushed back a little in depth so the incision's lines win over the faces they bound.
      polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
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
    // The fixed vertices' places (the mechanical surface's; the surface drawn may be a finer one).
    const fixed = new Float32Array(msg.fixed_points);
    const fgeo = new THREE.BufferGeometry();
    fgeo.setAttribute('position', new THREE.BufferAttribute(fixed, 3));
    this.fixed = new THREE.Points(fgeo, new THREE.PointsMaterial({
      color: 0x64b5f6, size: msg.size * 0.022, map: this.dot, alphaTest: 0.3, transparent: true,
    }));
    this.fixed.visible = this.showFixed;
    // The incision: edges that bound only one triangle. A closed organ has none; a cut
    // opens the surface, and its lips are drawn as dark lines from the frame the new
    // surface arrives in, whether or not the model has pulled them apart yet.
    this.openEdges = boundaryEdges(msg.triangles);
    const egeo = new THREE.BufferGeometry();
    egeo.setAttribute('position', new THREE.BufferAttribute(new Float32Array(this.openEdges.length * 3), 3));
    this.incision = new THREE.LineSegments(egeo, new THREE.LineBasicMaterial({ color: 0x1a0302 }));
    this.incision.visible = this.openEdges.length > 0;
    this.incision.renderOrder = 2;
    // The lips' vertices are painted the dark red of cut tissue, a band one triangle wide.
    this.lips = new Uint8Array(rest.length / 3);
    for (const v of this.openEdges) this.lips[v] = 1;
    this.group.add(this.mesh, this.wire, this.restMesh, this.fixed, this.incision);
    this.updateIncision(rest);
    this.probe.scale.setScalar(msg.probe_radius);
    this.ghost.scale.setScalar(msg.probe_radius);
    this.colourScale = 0;
    this.maxDisplacement = 0;
    this.paint();
  }

  updateIncision(pos) {
    if (!this.openEdges.length) return;
    const attr = this.incision.geometry.attributes.position;
    this.openEdges.forEach((v, i) => attr.array.set(pos.subarray(3 * v, 3 * v + 3), 3 * i));
    attr.needsUpdate = true;
    this.incision.geometry.computeBoundingSphere();
  }

  /// Forgets the colour scales' maxima (after the server's reset). No repaint: the positions
  /// shown are still the pre-reset ones, and would set the scale again; the next frame does.
  rescale() { this.colourScale = 0; this.strainScale = 0; }

  setQuantity(q) { this.quantity = q; this.paint(); }

  /// True when the colours can show strain (the model has tetrahedra).
  hasStrain() { return !!this.strain; }

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
    let value = disp, scale = this.colourScale;
    if (this.quantity === 'strain' && this.strain) {
      let top = 0;
      for (const e of this.strain) if (e > top) top = e;
      // Never below 0.1 % strain: an organ at rest is uniformly blue, not noise.
      this.strainScale = Math.max(this.strainScale, top, 1e-3);
      value = this.strain;
      scale = this.strainScale;
    }
    for (let i = 0; i < disp.length; i++) {
      if (this.colours) colormap(value[i] / scale, col, 3 * i);
      else if (this.lips && this.lips[i]) col.set(CUT_COLOUR, 3 * i);
      else col.set(this.labels ? PART_COLOURS[this.labels[i]] || TISSUE_COLOUR : TISSUE_COLOUR, 3 * i);
    }
    this.mesh.geometry.attributes.color.needsUpdate = true;
  }

  frame(msg) {
    if (!this.mesh) return;
    const attr = this.mesh.geometry.attributes.position;
    if (msg.positions.length !== attr.array.length) return; // a new init is on its way
    attr.array.set(msg.positions);
    this.labels = msg.labels && msg.labels.length === attr.array.length / 3 ? msg.labels : null;
    this.strain = msg.strain && msg.strain.length === attr.array.length / 3 ? msg.strain : null;
    if (this.smoother) this.smoother.apply(attr.array);
    attr.needsUpdate = true;
    this.mesh.geometry.computeVertexNormals();
    this.mesh.geometry.computeBoundingSphere();
    this.updateIncision(attr.array);
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
    if (this.blade.visible) setLine(this.blade, msg.scalpel.blade.map(v));
    // The force on the active tool, drawn at its tip.
    const tool = msg.grasper ? msg.grasper : (msg.probe_active ? msg.probe : null);
    const f = msg.grasper ? v(msg.grasper.force) : v(msg.haptic_force);
    const n = f.length();
    this.arrow.visible = !!tool && n > 1e-9;
    if (this.arrow.visible) {
      this.arrow.position.copy(v(tool.position));
      this.arrow.setDirection(f.clone().divideScalar(n));
      // At most a quarter of the organ: half of that at 0.5 N.
      const len = this.size * 0.25 * n / (n + 0.5);
      this.arrow.setLength(len, Math.min(len * 0.3, this.size * 0.04), Math.min(len * 0.15, this.size * 0.02));
    }
    return n;
  }

  showCutPath(points) {
    setLine(this.cutLine, points);
    setLine(this.cutDots, points);
    this.cutLine.visible = points.length > 1;
    this.cutDots.visible = points.length > 0;
  }
}

// Vertex pairs (flattened) of the edges used by exactly one triangle.
function boundaryEdges(tris) {
  const count = new Map();
  for (let t = 0; t < tris.length; t += 3) {
    for (let k = 0; k < 3; k++) {
      const a = tris[t + k], b = tris[t + (k + 1) % 3];
      const key = a < b ? a * 4294967296 + b : b * 4294967296 + a;
      count.set(key, (count.get(key) || 0) + 1);
    }
  }
  const out = [];
  for (const [key, n] of count) {
    if (n === 1) out.push(Math.floor(key / 4294967296), key % 4294967296);
  }
  return out;
}

// Taubin smoothing (lambda|mu), uniform weights over the mesh's edge neighbours, in place.
class Smoother {
  constructor(tris, n, passes = 6) {
    const sets = Array.from({ length: n }, () => new Set());
    for (let t = 0; t < tris.length; t += 3) {
      for (let k = 0; k < 3; k++) {
        const a = tris[t + k], b = tris[t + (k + 1) % 3];
        sets[a].add(b); sets[b].add(a);
      }
    }
    this.start = new Uint32Array(n + 1);
    for (let i = 0; i < n; i++) this.start[i + 1] = this.start[i] + sets[i].size;
    this.nbr = new Uint32Array(this.start[n]);
    sets.forEach((set, i) => { let j = this.start[i]; for (const v of set) this.nbr[j++] = v; });
    this.tmp = new Float32Array(3 * n);
    this.passes = passes;
    this.n = n;
  }

  apply(pos) {
    for (let p = 0; p < this.passes; p++) {
      this.relax(pos, 0.5);
      this.relax(pos, -0.53);
    }
  }

  relax(pos, f) {
    const { start, nbr, tmp, n } = this;
    for (let i = 0; i < n; i++) {
      const a = start[i], b = start[i + 1];
      if (a === b) { tmp[3 * i] = pos[3 * i]; tmp[3 * i + 1] = pos[3 * i + 1]; tmp[3 * i + 2] = pos[3 * i + 2]; continue; }
      let x = 0, y = 0, z = 0;
      for (let j = a; j < b; j++) { const v = 3 * nbr[j]; x += pos[v]; y += pos[v + 1]; z += pos[v + 2]; }
      const m = 1 / (b - a);
      tmp[3 * i] = pos[3 * i] + f * (x * m - pos[3 * i]);
      tmp[3 * i + 1] = pos[3 * i + 1] + f * (y * m - pos[3 * i + 1]);
      tmp[3 * i + 2] = pos[3 * i + 2] + f * (z * m - pos[3 * i + 2]);
    }
    pos.set(tmp);
  }
}
