// A small orbit camera: right drag (or shift + left drag) rotates about the organ's centre,
// the wheel zooms. Left drag without shift is left to the tools.
import * as THREE from 'three';

export class Orbit {
  constructor(camera, dom) {
    this.camera = camera;
    this.target = new THREE.Vector3();
    this.radius = 1;
    this.theta = 0.6;   // azimuth
    this.phi = 1.1;     // polar angle from +y
    this.drag = null;
    dom.addEventListener('contextmenu', (e) => e.preventDefault());
    dom.addEventListener('pointerdown', (e) => {
      if (e.button === 2 || (e.button === 0 && e.shiftKey)) {
        this.drag = { x: e.clientX, y: e.clientY, id: e.pointerId };
        dom.setPointerCapture(e.pointerId);
        e.stopImmediatePropagation();
      }
    }, { capture: true });
    dom.addEventListener('pointermove', (e) => {
      if (!this.drag) return;
      this.theta -= (e.clientX - this.drag.x) * 0.008;
      this.phi = Math.min(3.1, Math.max(0.05, this.phi - (e.clientY - this.drag.y) * 0.008));
      this.drag.x = e.clientX; this.drag.y = e.clientY;
      this.update();
      e.stopImmediatePropagation();
    }, { capture: true });
    const end = (e) => { if (this.drag) { this.drag = null; e.stopImmediatePropagation(); } };
    dom.addEventListener('pointerup', end, { capture: true });
    dom.addEventListener('pointercancel', end, { capture: true });
    dom.addEventListener('wheel', (e) => {
      e.preventDefault();
      this.radius *= Math.exp(e.deltaY * 0.001);
      this.update();
    }, { passive: false });
  }

  frame(center, size) {
    this.target.copy(center);
    this.radius = 2.2 * size;
    this.update();
  }

  update() {
    const s = Math.sin(this.phi);
    const offset = new THREE.Vector3(
      this.radius * s * Math.sin(this.theta),
      this.radius * Math.cos(this.phi),
      this.radius * s * Math.cos(this.theta));
    this.camera.position.copy(this.target).add(offset);
    this.camera.near = this.radius * 0.01;
    this.camera.far = this.radius * 100;
    this.camera.updateProjectionMatrix();
    this.camera.lookAt(this.target);
  }
}
