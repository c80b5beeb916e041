// Rolling plot of the force magnitude on a 2D canvas.
export class RollingPlot {
  constructor(canvas, seconds = 10) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.seconds = seconds;
    this.samples = []; // [time_ms, value]
  }

  push(value) {
    const now = performance.now();
    this.samples.push([now, value]);
    while (this.samples.length && this.samples[0][0] < now - this.seconds * 1000) this.samples.shift();
  }

  draw() {
    const { ctx, canvas } = this;
    const w = canvas.width, h = canvas.height;
    ctx.clearRect(0, 0, w, h);
    const max = Math.max(1e-3, ...this.samples.map((s) => s[1]));
    ctx.strokeStyle = '#ffb74d';
    ctx.beginPath();
    const now = performance.now();
    this.samples.forEach(([t, v], i) => {
      const x = w - ((now - t) / (this.seconds * 1000)) * w;
      const y = h - 4 - (v / max) * (h - 14);
      if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
    });
    ctx.stroke();
    ctx.fillStyle = '#99a';
    ctx.font = '10px sans-serif';
    ctx.fillText(`${max.toFixed(3)} N`, 4, 10);
  }
}
