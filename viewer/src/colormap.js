// Displacement colour map: blue (0) -> cyan -> green -> yellow -> red (max).
const STOPS = [
  [0.0, [0.10, 0.20, 0.80]],
  [0.25, [0.10, 0.70, 0.90]],
  [0.5, [0.20, 0.80, 0.30]],
  [0.75, [0.95, 0.85, 0.20]],
  [1.0, [0.90, 0.15, 0.10]],
];

export function colormap(t, out, k) {
  const x = Math.min(1, Math.max(0, t));
  for (let i = 1; i < STOPS.length; i++) {
    const [t1, c1] = STOPS[i];
    if (x <= t1) {
      const [t0, c0] = STOPS[i - 1];
      const u = (x - t0) / (t1 - t0);
      out[k] = c0[0] + u * (c1[0] - c0[0]);
      out[k + 1] = c0[1] + u * (c1[1] - c0[1]);
      out[k + 2] = c0[2] + u * (c1[2] - c0[2]);
      return;
    }
  }
}

// Liver-like: a deep red-brown (linear RGB, as three.js vertex colours are).
export const TISSUE_COLOUR = [0.42, 0.085, 0.06];

// The colour map as a CSS gradient for the legend. Vertex colours are linear; the screen
// shows them through sRGB, so the legend converts the stops the same way.
const toSrgb = (c) => Math.round(255 * (c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055));
export function legendGradient() {
  const stops = STOPS.map(([t, c]) => `rgb(${c.map(toSrgb).join(',')}) ${(100 * t).toFixed(0)}%`);
  return `linear-gradient(to right, ${stops.join(', ')})`;
}
