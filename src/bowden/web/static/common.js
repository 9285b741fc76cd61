// Shared by the operator pages: the session token, JSON requests that carry it, and a scrolling plot.
"use strict";

const Bowden = (() => {
  const TOKEN_KEY = "bowden-session-token";

  // The token arrives in the URL fragment (#token=...), which browsers never send to the server;
  // it is kept in sessionStorage (gone when the tab closes) and removed from the address bar.
  function takeTokenFromUrl() {
    const match = /(?:^#|&)token=([^&]+)/.exec(location.hash);
    if (match) {
      sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(match[1]));
      history.replaceState(null, "", location.pathname + location.search);
    }
  }

  function token() {
    return sessionStorage.getItem(TOKEN_KEY) || "";
  }

  function setToken(value) {
    sessionStorage.setItem(TOKEN_KEY, value.trim());
  }

  // Wire a token field: shown when no token is stored yet, and again whenever the server refuses the
  // stored one (a restarted server has a new token); a pasted token calls `changed`.
  function tokenField(input, box, changed) {
    takeTokenFromUrl();
    box.hidden = token() !== "";
    input.addEventListener("change", () => {
      setToken(input.value);
      if (changed) { changed(); }
    });
  }

  function tokenRefused(input, box) {
    box.hidden = false;
    input.value = "";
  }

  // Whether a trial is running (the console's pages share it).
  let running = false;
  function setBusy(value) { running = value; }
  function busy() { return running; }

  // `refused`: the server refused the token that is still this tab's. A refusal of a request sent with
  // an older one (in flight while the operator pasted the new token) is not a refusal of the new one.
  async function request(method, path, body) {
    const sent = token();
    const options = { method, headers: { "X-Bowden-Token": sent } };
    if (body !== undefined) {
      options.headers["Content-Type"] = "application/json";
      options.body = JSON.stringify(body);
    }
    const response = await fetch(path, options);
    let data = null;
    try {
      data = await response.json();
    } catch (error) {
      data = { error: `HTTP ${response.status}` };
    }
    const refused = response.status === 403 && sent === token();
    return { ok: response.ok, status: response.status, data, refused };
  }

  // A plot of several series against time, scrolling with the newest sample.
  class ScrollingPlot {
    constructor(canvas, { windowS, series, unit, min, max }) {
      this.canvas = canvas;
      this.ctx = canvas.getContext("2d");
      this.windowS = windowS;
      this.series = series;  // [{key, label, color}]
      this.unit = unit;
      this.fixedMin = min;
      this.fixedMax = max;
      this.clear();
    }

    clear() {
      this.t = [];
      this.values = Object.fromEntries(this.series.map((s) => [s.key, []]));
    }

    push(message) {
      const n = message.t.length;
      for (let i = 0; i < n; i += 1) {
        this.t.push(message.t[i]);
        for (const s of this.series) {
          const column = message[s.key];
          this.values[s.key].push(column ? column[i] : null);
        }
      }
      const newest = this.t.length ? this.t[this.t.length - 1] : 0;
      let drop = 0;
      while (drop < this.t.length && this.t[drop] < newest - this.windowS - 1) {
        drop += 1;
      }
      if (drop > 0) {
        this.t.splice(0, drop);
        for (const s of this.series) { this.values[s.key].splice(0, drop); }
      }
    }

    draw() {
      const canvas = this.canvas;
      const dpr = window.devicePixelRatio || 1;
      const w = Math.round(canvas.clientWidth * dpr);
      const h = Math.round(canvas.clientHeight * dpr);
      if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
      const ctx = this.ctx;
      ctx.fillStyle = "#ffffff";
      ctx.fillRect(0, 0, w, h);
      const left = 52 * dpr;
      const right = w - 8 * dpr;
      const top = 22 * dpr;
      const bottom = h - 18 * dpr;
      let lo = this.fixedMin;
      let hi = this.fixedMax;
      if (lo === undefined || hi === undefined) {
        lo = Infinity; hi = -Infinity;
        for (const s of this.series) {
          for (const v of this.values[s.key]) {
            if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
          }
        }
        if (!Number.isFinite(lo)) { lo = 0; hi = 1; }
        const pad = Math.max(0.1 * (hi - lo), 0.5);
        lo -= pad; hi += pad;
      }
      const newest = this.t.length ? this.t[this.t.length - 1] : 0;
      const x = (t) => right - ((newest - t) / this.windowS) * (right - left);
      const y = (v) => bottom - ((v - lo) / (hi - lo)) * (bottom - top);
      ctx.font = `${11 * dpr}px sans-serif`;
      ctx.strokeStyle = "#d9dde5";
      ctx.fillStyle = "#555c6b";
      ctx.lineWidth = dpr;
      ctx.textBaseline = "middle";
      for (let k = 0; k <= 4; k += 1) {
        const v = lo + ((hi - lo) * k) / 4;
        ctx.beginPath(); ctx.moveTo(left, y(v)); ctx.lineTo(right, y(v)); ctx.stroke();
        ctx.fillText(v.toFixed(Math.abs(hi - lo) < 5 ? 2 : 0), 4 * dpr, y(v));
      }
      let legendX = left;
      ctx.textBaseline = "top";
      this.series.forEach((s, index) => {
        ctx.fillStyle = s.color;
        ctx.fillText(`${s.label} (${this.unit})`, legendX, 4 * dpr);
        legendX += ctx.measureText(`${s.label} (${this.unit})`).width + 16 * dpr;
        ctx.strokeStyle = s.color;
        // The first series (the target) is drawn widest so that a close follower does not hide it.
        ctx.lineWidth = (index === 0 ? 3.5 : 1.5) * dpr;
        ctx.beginPath();
        let started = false;
        const values = this.values[s.key];
        for (let i = 0; i < this.t.length; i += 1) {
          if (values[i] === null || this.t[i] < newest - this.windowS) { started = false; continue; }
          if (!started) { ctx.moveTo(x(this.t[i]), y(values[i])); started = true; }
          else { ctx.lineTo(x(this.t[i]), y(values[i])); }
        }
        ctx.stroke();
      });
    }
  }

  return { takeTokenFromUrl, token, setToken, tokenField, tokenRefused, setBusy, busy, request, ScrollingPlot };
})();
