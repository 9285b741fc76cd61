// Participant display: the reference scrolling towards a fixed "now" line and the measured elevation
// drawn over it, redrawn on every animation frame; the repetition count in large type.
// Read-only: it listens to /ws/display and offers nothing to click.
"use strict";

(() => {
  const PAST_S = 3.0;        // history shown left of the "now" line
  const AHEAD_S = 5.0;       // reference shown ahead
  const NOW_FRACTION = 0.3;  // where "now" sits across the screen
  const MIN_DEG = 0;
  const MAX_DEG = 120;
  const TRACE_LIMIT = 200000;
  const LATENCY_LIMIT = 20000;
  const COLORS = {
    background: "#0b0d12",
    grid: "#2a2f3a",
    gridText: "#8b93a7",
    reference: "#4fa3ff",
    measured: "#ffb020",
    now: "#e8ecf4",
    text: "#f4f6fb",
  };

  const canvas = document.getElementById("display");
  const ctx = canvas.getContext("2d", { alpha: false });

  const state = {
    connected: false,
    reference: null,   // numbers of TrialReference.to_json(), or null when idle
    running: false,
    stopped: false,    // the last trial was stopped before its end (not completed)
    trace: [],         // [t_s, elevation_deg, seq, stamp_ms] of the current trial, oldest first
    lastT: null,
    unpresented: [],   // samples received since the last frame
    drawn: [],         // samples drawn in the last frame, waiting for its presentation time
    latency: [],       // {seq, stamp_ms, drawn_ms, presented_ms}
    frameTimes: [],
  };

  // --- connection ---------------------------------------------------------------------------------
  function connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const socket = new WebSocket(`${scheme}://${location.host}/ws/display`);
    socket.onopen = () => { state.connected = true; };
    socket.onclose = () => {
      state.connected = false;
      setTimeout(connect, 1000);
    };
    socket.onmessage = (event) => handle(JSON.parse(event.data));
  }

  function handle(message) {
    if (message.type === "trial") {
      if (message.state === "running") {
        const fresh = !state.running || JSON.stringify(message.reference) !== JSON.stringify(state.reference);
        state.reference = message.reference;
        state.running = true;
        state.stopped = false;
        if (fresh) {
          state.trace = [];
          state.lastT = null;
        }
      } else {
        state.running = false;
      }
    } else if (message.type === "samples") {
      const n = message.t.length;
      for (let i = 0; i < n; i += 1) {
        const sample = [message.t[i], message.elevation_deg[i], message.seq[i], message.stamp_ms[i]];
        state.trace.push(sample);
        state.unpresented.push(sample);
      }
      if (state.trace.length > TRACE_LIMIT) {
        state.trace.splice(0, state.trace.length - TRACE_LIMIT);
      }
      if (n > 0) {
        state.lastT = message.t[n - 1];
      }
    } else if (message.type === "stopped") {
      state.running = false;
      state.stopped = message.completed === false;
    }
  }

  // --- drawing ------------------------------------------------------------------------------------
  function geometry() {
    const w = canvas.width;
    const h = canvas.height;
    const top = 0.16 * h;
    const bottom = 0.94 * h;
    const nowX = NOW_FRACTION * w;
    const pxPerS = (w - nowX) / AHEAD_S;
    const tNow = state.lastT === null ? 0 : state.lastT;
    return {
      w, h, nowX, pxPerS, tNow,
      x: (t) => nowX + (t - tNow) * pxPerS,
      y: (deg) => top + ((MAX_DEG - deg) / (MAX_DEG - MIN_DEG)) * (bottom - top),
    };
  }

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(window.innerWidth * dpr);
    const h = Math.round(window.innerHeight * dpr);
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
  }

  const GRID_DEG = [20, 60, 100];

  // Type scales with the shorter side, so a portrait tablet gets the same proportions as a monitor.
  function unitOf(g) {
    return Math.min(g.h, 1.4 * g.w) / 100;
  }

  function drawGrid(g) {
    ctx.lineWidth = Math.max(1, 0.2 * unitOf(g));
    ctx.strokeStyle = COLORS.grid;
    for (const deg of GRID_DEG) {
      ctx.beginPath();
      ctx.moveTo(0, g.y(deg));
      ctx.lineTo(g.w, g.y(deg));
      ctx.stroke();
    }
  }

  // The grid labels, drawn after the traces on a backing of the page colour: the reference sweeps the
  // whole width and would otherwise cross them (a portrait screen brings the 60° label into its path).
  function labelBoxes(g) {
    const unit = unitOf(g);
    ctx.font = `${Math.round(2.6 * unit)}px sans-serif`;
    return GRID_DEG.map((deg) => {
      const text = `${deg}°`;
      const w = ctx.measureText(text).width + 1.2 * unit;
      const h = 3.4 * unit;
      return { deg, text, x: 0.99 * g.w - w, y: g.y(deg) - 2.6 * unit - h / 2, w, h };
    });
  }

  function drawLabels(g) {
    ctx.textBaseline = "middle";
    ctx.textAlign = "center";
    for (const box of labelBoxes(g)) {
      ctx.fillStyle = COLORS.background;
      ctx.fillRect(box.x, box.y, box.w, box.h);
      ctx.fillStyle = COLORS.gridText;
      ctx.fillText(box.text, box.x + box.w / 2, box.y + box.h / 2);
    }
    ctx.textAlign = "left";
  }

  function drawReference(g) {
    const ref = state.reference;
    const unit = g.h / 100;
    ctx.strokeStyle = COLORS.reference;
    ctx.lineWidth = 1.6 * unit;
    ctx.lineJoin = "round";
    ctx.lineCap = "round";
    ctx.beginPath();
    const t0 = g.tNow - g.nowX / g.pxPerS;
    const t1 = g.tNow + AHEAD_S;
    const step = 3 / g.pxPerS;  // one vertex every 3 pixels
    for (let t = t0; t <= t1 + step; t += step) {
      const x = g.x(t);
      const y = g.y(BowdenReference.elevationDeg(ref, t));
      if (t === t0) { ctx.moveTo(x, y); } else { ctx.lineTo(x, y); }
    }
    ctx.stroke();
  }

  function drawMeasured(g) {
    const trace = state.trace;
    if (trace.length === 0) {
      return;
    }
    const unit = g.h / 100;
    const t0 = g.tNow - PAST_S - 0.5;
    let first = trace.length - 1;
    while (first > 0 && trace[first - 1][0] >= t0) {
      first -= 1;
    }
    ctx.strokeStyle = COLORS.measured;
    ctx.lineWidth = 1.2 * unit;
    ctx.lineJoin = "round";
    ctx.lineCap = "round";
    ctx.beginPath();
    let started = false;
    for (let i = first; i < trace.length; i += 1) {
      const el = trace[i][1];
      if (el === null) { started = false; continue; }
      const x = g.x(trace[i][0]);
      const y = g.y(el);
      if (!started) { ctx.moveTo(x, y); started = true; } else { ctx.lineTo(x, y); }
    }
    ctx.stroke();
    const last = trace[trace.length - 1];
    if (last[1] !== null) {
      ctx.fillStyle = COLORS.measured;
      ctx.beginPath();
      ctx.arc(g.x(last[0]), g.y(last[1]), 2.4 * unit, 0, 2 * Math.PI);
      ctx.fill();
    }
  }

  function drawNowLine(g) {
    ctx.strokeStyle = COLORS.now;
    ctx.lineWidth = Math.max(1, 0.25 * g.h / 100);
    ctx.setLineDash([g.h / 100, g.h / 100]);
    ctx.beginPath();
    ctx.moveTo(g.nowX, 0.12 * g.h);
    ctx.lineTo(g.nowX, g.h);
    ctx.stroke();
    ctx.setLineDash([]);
  }

  function headline(g) {
    const ref = state.reference;
    if (ref === null) {
      return state.connected ? "Please wait for the next trial" : "Connecting…";
    }
    const rep = BowdenReference.repetition(ref, g.tNow);
    if (state.stopped) {
      return "Stopped — rest";
    }
    if (!state.running || g.tNow >= BowdenReference.endS(ref)) {
      return `Done: ${ref.repetitions} of ${ref.repetitions} — rest`;
    }
    if (rep === 0) {
      return "Get ready";
    }
    return `Repetition ${rep} of ${ref.repetitions}`;
  }

  // The headline's font: 8 % of the height, made smaller until the text fits 94 % of the width.
  function headlineFont(g, text) {
    let size = Math.round(8 * g.h / 100);
    ctx.font = `bold ${size}px sans-serif`;
    const width = ctx.measureText(text).width;
    if (width > 0.94 * g.w) {
      size = Math.floor(size * (0.94 * g.w) / width);
      ctx.font = `bold ${size}px sans-serif`;
    }
    return size;
  }

  function drawText(g) {
    const text = headline(g);
    headlineFont(g, text);
    ctx.fillStyle = COLORS.text;
    ctx.textBaseline = "top";
    ctx.textAlign = "center";
    ctx.fillText(text, g.w / 2, 2 * g.h / 100);
    ctx.textAlign = "left";
  }

  function frame(timestamp) {
    const presented = performance.timeOrigin + timestamp;
    // This frame's start is when the previous frame's pixels were handed to the screen.
    for (const sample of state.drawn) {
      state.latency.push({ seq: sample[2], stamp_ms: sample[3], drawn_ms: sample.drawnMs, presented_ms: presented });
    }
    if (state.latency.length > LATENCY_LIMIT) {
      state.latency.splice(0, state.latency.length - LATENCY_LIMIT);
    }
    state.drawn = [];
    state.frameTimes.push(timestamp);
    if (state.frameTimes.length > 600) {
      state.frameTimes.shift();
    }

    resize();
    const g = geometry();
    ctx.fillStyle = COLORS.background;
    ctx.fillRect(0, 0, g.w, g.h);
    drawGrid(g);
    if (state.reference !== null) {
      drawReference(g);
      drawNowLine(g);
      drawMeasured(g);  // last of the traces, so the participant's own dot is never hidden
    }
    drawLabels(g);
    drawText(g);

    const drawnMs = performance.timeOrigin + performance.now();
    for (const sample of state.unpresented) {
      sample.drawnMs = drawnMs;
      state.drawn.push(sample);
    }
    state.unpresented = [];
    requestAnimationFrame(frame);
  }

  // Nothing on this page reacts to the pointer; the context menu is suppressed too.
  document.addEventListener("contextmenu", (event) => event.preventDefault());

  // For tests and the latency benchmark (read-only views of the state).
  window.bowdenDisplay = {
    trace: () => state.trace.map((s) => [s[0], s[1]]),
    reference: () => state.reference,
    running: () => state.running,
    connected: () => state.connected,
    headline: () => headline(geometry()),
    headlineWidth: () => {
      const g = geometry();
      const text = headline(g);
      headlineFont(g, text);
      return { text: ctx.measureText(text).width, canvas: g.w };
    },
    labelBoxes: () => labelBoxes(geometry()).map(({ deg, x, y, w, h }) => ({ deg, x, y, w, h })),
    latency: () => state.latency.slice(),
    framesPerSecond: () => {
      const times = state.frameTimes;
      if (times.length < 2) { return 0; }
      return (1000 * (times.length - 1)) / (times[times.length - 1] - times[0]);
    },
    toCanvas: (t, deg) => { const g = geometry(); return [g.x(t), g.y(deg)]; },
    lastT: () => state.lastT,
    colors: COLORS,
  };

  connect();
  requestAnimationFrame(frame);
})();
