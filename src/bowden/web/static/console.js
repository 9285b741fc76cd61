// Operator console: choose and start a trial, stop it (safe state), watch plots and loop health.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const form = $("trial-form");
  const message = $("message");
  const banner = $("fault-banner");
  let options = null;
  let socket = null;
  let running = false;

  Bowden.tokenField($("token"), $("token-box"));

  const plots = {
    tension: new Bowden.ScrollingPlot($("plot-tension"), {
      windowS: 10, unit: "N", series: [
        { key: "desired_tension_n", label: "desired", color: "#1f5fbf" },
        { key: "estimated_tension_n", label: "estimated from torque", color: "#d9480f" },
        { key: "load_cell_tension_n", label: "load cell", color: "#2b8a3e" },
      ],
    }),
    torque: new Bowden.ScrollingPlot($("plot-torque"), {
      windowS: 10, unit: "Nm", series: [
        { key: "commanded_torque_nm", label: "commanded", color: "#1f5fbf" },
        { key: "motor_torque_nm", label: "measured", color: "#d9480f" },
      ],
    }),
    elevation: new Bowden.ScrollingPlot($("plot-elevation"), {
      windowS: 10, unit: "°", min: 0, max: 120, series: [
        { key: "reference_deg", label: "reference", color: "#1f5fbf" },
        { key: "elevation_deg", label: "measured", color: "#d9480f" },
      ],
    }),
  };

  function say(text, isError) {
    message.textContent = text;
    message.classList.toggle("error", Boolean(isError));
  }

  function showBanner(text) {
    banner.textContent = text;
    banner.hidden = !text;
  }

  function setRunning(value) {
    running = value;
    $("start").disabled = value;
    $("trial-state").textContent = value ? "running" : "idle";
    $("trial-state").classList.toggle("live", value);
    for (const element of form.querySelectorAll("input, select")) {
      element.disabled = value;
    }
    if (!value) { updateSupportField(); }
  }

  function updateSupportField() {
    if (!options) { return; }
    const condition = options.conditions.find((c) => c.id === $("condition").value);
    const support = $("support");
    const numeric = typeof condition.support === "number";
    support.disabled = running || !numeric;
    support.value = numeric ? String(condition.support) : "";
    support.placeholder = numeric ? "" : (condition.support === null ? "no suit" : "pretension");
  }

  async function loadOptions() {
    const response = await fetch("/api/options");
    options = await response.json();
    for (const c of options.conditions) {
      $("condition").append(new Option(`${c.label} (${c.id})`, c.id));
    }
    for (const s of options.speeds) {
      $("speed").append(new Option(`${s.id} (${s.peak_deg_s} °/s peak)`, s.id));
    }
    $("repetitions").value = String(options.repetitions);
    $("condition").addEventListener("change", updateSupportField);
    updateSupportField();
  }

  function trialRequest() {
    const body = {
      participant: $("participant").value.trim(),
      condition: $("condition").value,
      speed: $("speed").value,
      repetitions: $("repetitions").value,
      height_m: $("height_m").value,
      mass_kg: $("mass_kg").value,
      sex: $("sex").value,
    };
    if (!$("support").disabled && $("support").value !== "") {
      body.support = $("support").value;
    }
    return body;
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    say("Starting…");
    const result = await Bowden.request("POST", "/api/trial/start", trialRequest());
    if (result.ok) {
      say(`Trial ${result.data.trial_id} running.`);
      setRunning(true);
    } else {
      say(result.data.error || `refused (HTTP ${result.status})`, true);
    }
    if (result.status !== 403 && socket === null) { connect(); }
  });

  $("stop").addEventListener("click", async () => {
    const result = await Bowden.request("POST", "/api/trial/stop", {});
    if (result.ok) {
      say("Stop requested: ramping the torque to zero and leaving motor mode…");
    } else {
      say(result.data.error || `refused (HTTP ${result.status})`, true);
    }
  });

  function showHealth(h) {
    $("h-state").textContent = h.state;
    if (h.state === "idle") { return; }
    $("h-time").textContent = `${h.trial_time_s.toFixed(1)} s`;
    $("h-cycles").textContent = String(h.cycles);
    $("h-late").textContent = `${h.deadline_misses} (${h.skipped_cycles} skipped)`;
    $("h-worst").textContent = `${h.worst_lateness_ms.toFixed(2)} ms`
      + (h.simulation_lag_ms !== undefined ? ` · simulation lag ${h.simulation_lag_ms.toFixed(1)} ms` : "");
    $("h-faults").textContent = h.faults.length ? h.faults.join(", ") : "none";
    $("h-fault-cycles").textContent = String(h.fault_cycles);
    $("h-rows").textContent = String(h.committed_rows);
    if (h.faults.length) {
      showBanner(`FAULT: ${h.faults.join(", ")} — the loop commands zero torque on faulted cycles`);
    } else if (h.faults_seen.length) {
      showBanner(`Faults during this trial: ${h.faults_seen.join(", ")} (${h.fault_cycles} cycles)`);
    }
  }

  function handle(data) {
    if (data.type === "error") {
      say(data.error, true);
    } else if (data.type === "trial") {
      if (data.state === "running") {
        Object.values(plots).forEach((p) => p.clear());
        showBanner("");
        setRunning(true);
        $("h-suit").textContent = data.suit;
        const s = data.setup;
        $("last-result").textContent =
          `Trial ${data.trial_id}: ${s.participant}, ${s.condition}, ${s.speed}, ${s.repetitions} repetitions`;
      } else {
        setRunning(false);
      }
      if (data.last_result) { showResult(data.last_result); }
    } else if (data.type === "samples") {
      Object.values(plots).forEach((p) => p.push(data));
    } else if (data.type === "health") {
      showHealth(data);
    } else if (data.type === "stopped") {
      setRunning(false);
      showResult(data);
    }
  }

  function showResult(r) {
    const text = `Trial ${r.trial_id} ended: ${r.reason}. ${r.committed_rows} rows recorded.`
      + (r.timing ? ` ${r.timing}.` : "");
    $("last-result").textContent = text;
    $("h-state").textContent = r.clean ? "safe (ended)" : "safe (FAULT)";
    if (!r.clean) {
      showBanner(`Trial stopped on a fault: ${r.reason}${r.faults && r.faults.length ? ` (${r.faults.join(", ")})` : ""}`);
    }
  }

  function connect() {
    if (!Bowden.token()) {
      $("connection").textContent = "no token";
      return;
    }
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    socket = new WebSocket(`${scheme}://${location.host}/ws/console`);
    socket.onopen = () => {
      socket.send(JSON.stringify({ token: Bowden.token() }));
      $("connection").textContent = "live";
      $("connection").classList.add("live");
    };
    socket.onclose = (event) => {
      $("connection").textContent = event.code === 1008 ? "token refused" : "offline";
      $("connection").classList.remove("live");
      socket = null;
      if (event.code !== 1008) { setTimeout(connect, 1000); }
    };
    socket.onmessage = (event) => handle(JSON.parse(event.data));
  }

  $("token").addEventListener("change", () => { if (socket === null) { connect(); } });

  function animate() {
    Object.values(plots).forEach((p) => p.draw());
    requestAnimationFrame(animate);
  }

  loadOptions().then(() => { connect(); requestAnimationFrame(animate); });
})();
