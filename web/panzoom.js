// Zoom and pan for a group of uPlot charts sharing one x axis (blocks or cycle time):
// the wheel zooms about the pointer, shift-drag or middle-drag pans, a plain drag zooms to
// the dragged span (uPlot's own), a double click shows everything. Every chart of the group
// follows, once per animation frame however many input events arrive in it, so that 10^5
// points per series keep panning smooth.

export class XGroup {
  constructor() {
    this.plots = [];
    this.pending = null;
    this.applying = false;
    this.listeners = [];
  }

  add(u) { this.plots.push(u); }
  clear() { for (const u of this.plots) u.destroy(); this.plots = []; }
  onChange(f) { this.listeners.push(f); }

  // The whole x range of the data (all plots of a group share it).
  full() {
    let lo = Infinity; let hi = -Infinity;
    for (const u of this.plots) {
      const x = u.data[0];
      if (x.length) { lo = Math.min(lo, x[0]); hi = Math.max(hi, x[x.length - 1]); }
    }
    return [lo, hi];
  }

  // Asks for [min, max] on every plot at the next frame (later asks in the frame win).
  request(min, max) {
    const [lo, hi] = this.full();
    const span = Math.min(max - min, hi - lo);
    if (!(span > 0)) return;
    // Keep the window inside the data: panning stops at either end.
    if (min < lo) { min = lo; max = lo + span; }
    if (max > hi) { max = hi; min = hi - span; }
    const first = this.pending === null;
    this.pending = [min, max];
    if (first) requestAnimationFrame(() => this.flush());
  }

  flush() {
    const p = this.pending;
    this.pending = null;
    if (p) this.apply(p[0], p[1]);
  }

  apply(min, max, except) {
    const t0 = performance.now();
    this.applying = true;
    try {
      for (const u of this.plots) {
        if (u === except) continue;
        u.batch(() => u.setScale('x', { min, max }));
      }
    } finally { this.applying = false; }
    for (const f of this.listeners) f(min, max);
    // Each redraw of the group, on the page's timeline (the large-job test reads them).
    performance.measure('plots-redraw', { start: t0 });
  }

  // The uPlot options this group needs on each of its charts.
  options() {
    const group = this;
    return {
      cursor: {
        drag: { x: true, y: false, setScale: true },
        bind: {
          // Shift- or middle-button drags pan; anything else is uPlot's zoom-to-selection.
          // (uPlot listens passively here: no preventDefault.)
          mousedown: (u, targ, handler) => (e) => {
            if (e.button === 1 || (e.button === 0 && e.shiftKey)) { group.startPan(u, e); return null; }
            return handler(e);
          },
        },
      },
      hooks: {
        // A zoom made on one chart (drag, double click) is followed by the others.
        setScale: [(u, key) => {
          if (key !== 'x' || group.applying) return;
          group.apply(u.scales.x.min, u.scales.x.max, u);
        }],
        ready: [(u) => u.over.addEventListener('wheel', (e) => group.wheel(u, e), { passive: false })],
      },
    };
  }

  wheel(u, e) {
    e.preventDefault();
    const { min, max } = this.pending ? { min: this.pending[0], max: this.pending[1] } : u.scales.x;
    const rect = u.over.getBoundingClientRect();
    const at = min + ((e.clientX - rect.left) / rect.width) * (max - min);
    const k = Math.pow(1.0015, e.deltaY); // about 0.86 per notch in, 1.16 out
    const [lo, hi] = this.full();
    const span = Math.min(hi - lo, Math.max((max - min) * k, (hi - lo) * 1e-6));
    const f = (at - min) / (max - min);
    this.request(at - f * span, at + (1 - f) * span);
  }

  startPan(u, e) {
    const rect = u.over.getBoundingClientRect();
    const x0 = e.clientX;
    const { min, max } = u.scales.x;
    const perPx = (max - min) / rect.width;
    const move = (m) => this.request(min - (m.clientX - x0) * perPx, max - (m.clientX - x0) * perPx);
    const up = () => { document.removeEventListener('mousemove', move); document.removeEventListener('mouseup', up); };
    document.addEventListener('mousemove', move);
    document.addEventListener('mouseup', up);
  }
}

// Merges two hooks objects (uPlot takes arrays of functions per hook).
export function mergeHooks(...all) {
  const out = {};
  for (const h of all) for (const [k, v] of Object.entries(h || {})) out[k] = [...(out[k] || []), ...v];
  return out;
}
