// Operator console: trials (the plan's next one, or one outside the plan), the STOP that must always
// get through, plots and loop health. The session plan itself is console_session.js.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const form = $("trial-form");
  const message = $("message");
  const banner = $("fault-banner");
  const STOP_RETRY_MS = 500;
  let options = null;
  let socket = null;
  let running = false;
  let registry = new Map();  // participant id → registration
  let stopRetry = null;

  function refused() {
    Bowden.tokenRefused($("token"), $("token-box"));
    $("connection").textContent = "token refused";
    $("connection").classList.remove("live");
  }

  Bowden.tokenField($("token"), $("token-box"), () => {
    $("token-box").hidden = true;
    if (socket !== null) { socket.close(); } else { connect(); }
    loadRegistry();
  });
  BowdenSession.init(refused);

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
    Bowden.setBusy(value);
    $("start").disabled = value;
    $("trial-state").textContent = value ? "running" : "idle";
    $("trial-state").classList.toggle("live", value);
    for (const element of form.querySelectorAll("input, select")) {
      element.disabled = value;
    }
    if (!value) { updateFields(); }
    const session = BowdenSession.current();
    if (session) { BowdenSession.show(session); }
  }

  function updateFields() {
    if (!options) { return; }
    const condition = options.conditions.find((c) => c.id === $("condition").value);
    const support = $("support");
    support.disabled = true;  // a trial runs its condition's support (the rule of serve and run)
    support.value = typeof condition.support === "number" ? String(condition.support) : "";
    support.placeholder = condition.support === null ? "no suit" : (condition.support === "pretension" ? "pretension" : "");
    const known = registry.get($("participant").value.trim());
    $("registered-note").hidden = !known;
    for (const [id, key] of [["height_m", "height_m"], ["mass_kg", "mass_kg"], ["sex", "sex"]]) {
      if (known) { $(id).value = String(known[key]); }
      $(id).disabled = running || Boolean(known);
    }
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
    $("condition").addEventListener("change", updateFields);
    $("participant").addEventListener("input", updateFields);
    updateFields();
  }

  async function loadRegistry() {
    if (!Bowden.token()) { return; }
    try {
      const result = await Bowden.request("GET", "/api/participants");
      if (result.ok) {
        registry = new Map(result.data.participants.map((p) => [p.participant, p]));
        updateFields();
      } else if (result.refused) {
        refused();
      }
    } catch (error) { /* offline: the socket's reconnection says so */ }
  }

  function trialRequest() {
    const body = {
      participant: $("participant").value.trim(),
      condition: $("condition").value,
      speed: $("speed").value,
      repetitions: $("repetitions").value,
    };
    if (!registry.has(body.participant)) {  // registered: the registry's values are used
      Object.assign(body, { height_m: $("height_m").value, mass_kg: $("mass_kg").value, sex: $("sex").value });
    }
    return body;
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    say("Starting…");
    let result;
    try {
      result = await Bowden.request("POST", "/api/trial/start", trialRequest());
    } catch (error) {
      say(`The server did not answer (${error.message}): nothing was started.`, true);
      return;
    }
    if (result.ok) {
      say(`Trial ${result.data.trial_id} running.`);
      setRunning(true);
      loadRegistry();
    } else {
      say(result.data.error || `refused (HTTP ${result.status})`, true);
      if (result.refused) { refused(); }
    }
    if (result.status !== 403 && socket === null) { connect(); }
  });

  // STOP must get through: a request that fails on the network is said, retried until the server
  // answers, and the button (and Escape) stay usable meanwhile.
  function stopSay(text, isError) {
    $("stop-message").textContent = text;
    $("stop-message").classList.toggle("error", Boolean(isError));
  }

  async function requestStop() {
    clearTimeout(stopRetry);
    stopRetry = null;
    let result;
    try {
      result = await Bowden.request("POST", "/api/trial/stop", {});
    } catch (error) {
      stopSay(`STOP did not reach the server (${error.message}): retrying… Press STOP or Escape again, `
        + "or use the suit's emergency stop.", true);
      stopRetry = setTimeout(requestStop, STOP_RETRY_MS);
      return;
    }
    if (result.ok) {
      stopSay("Stop requested: ramping the torque to zero and leaving motor mode…");
    } else {
      stopSay(result.data.error || `refused (HTTP ${result.status})`, true);
      if (result.refused) { refused(); }
    }
  }

  $("stop").addEventListener("click", requestStop);
  document.addEventListener("keydown", (event) => {
    if (event.key === "Escape") {
      event.preventDefault();
      requestStop();
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

  // A console (re)loaded during a trial shows that trial, not the defaults.
  function restore(setup) {
    $("participant").value = setup.participant;
    $("condition").value = setup.condition;
    $("speed").value = setup.speed;
    $("repetitions").value = String(setup.repetitions);
    for (const key of ["height_m", "mass_kg", "sex"]) { $(key).value = String(setup[key]); }
  }

  function handle(data) {
    if (data.type === "error") {
      say(data.error, true);
    } else if (data.type === "trial") {
      if (data.state === "running") {
        Object.values(plots).forEach((p) => p.clear());
        showBanner("");
        restore(data.setup);
        setRunning(true);
        $("h-suit").textContent = data.suit;
        const s = data.setup;
        $("last-result").textContent =
          `Trial ${data.trial_id} running: ${s.participant}, ${s.condition}, ${s.speed}, ${s.repetitions} repetitions`;
      } else {
        setRunning(false);
      }
      if (data.last_result && data.state !== "running") { showResult(data.last_result); }
    } else if (data.type === "samples") {
      Object.values(plots).forEach((p) => p.push(data));
    } else if (data.type === "health") {
      showHealth(data);
    } else if (data.type === "stopped") {
      clearTimeout(stopRetry);
      stopRetry = null;
      setRunning(false);
      showResult(data);
    } else if (data.type === "session") {
      BowdenSession.show(data);
    }
  }

  function showResult(r) {
    const how = r.completed ? "completed" : "stopped before its end";
    const text = `Trial ${r.trial_id} ${how}: ${r.reason}. ${r.committed_rows} rows recorded.`
      + (r.timing ? ` ${r.timing}.` : "")
      // The trigger line and LSL (bowden serve --trigger/--lsl): each edge's send time, a warning.
      + (r.sync && r.sync.length ? ` ${r.sync.join(" ")}` : "");
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
    const sent = Bowden.token();
    socket = new WebSocket(`${scheme}://${location.host}/ws/console`);
    socket.onopen = () => {
      socket.send(JSON.stringify({ token: sent }));
      $("connection").textContent = "live";
      $("connection").classList.add("live");
    };
    socket.onclose = (event) => {
      socket = null;
      // A refusal of a token that has since been replaced (the operator pasted the new one while
      // the server was still refusing the old) is not a refusal of the new one: connect with it.
      if (event.code === 1008 && sent === Bowden.token()) {
        refused();
        return;
      }
      $("connection").textContent = "offline";
      $("connection").classList.remove("live");
      setTimeout(connect, event.code === 1008 ? 0 : 1000);
    };
    socket.onmessage = (event) => handle(JSON.parse(event.data));
  }

  function animate() {
    Object.values(plots).forEach((p) => p.draw());
    requestAnimationFrame(animate);
  }

  document.addEventListener("bowden-registered", loadRegistry);
  window.bowdenConsole = { running: () => running, stopRetrying: () => stopRetry !== null };
  loadOptions().then(() => { connect(); loadRegistry(); requestAnimationFrame(animate); });
})();
