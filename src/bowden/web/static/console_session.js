// Operator console, session side: register a participant, open their session plan, start the next
// trial in one action, redo or skip a trial with a reason, the questionnaire prompt and the break timer.
// The server keeps the plan (study store); this page only shows the status it sends.
"use strict";

const BowdenSession = (() => {
  const $ = (id) => document.getElementById(id);
  let status = null;        // the last session status from the server
  let breakBase = null;     // {elapsed_s, length_s, at_ms}: the break timer ticks from here
  let onRefused = () => {};

  function say(text, isError) {
    $("session-message").textContent = text;
    $("session-message").classList.toggle("error", Boolean(isError));
  }

  async function call(method, path, body) {
    let result;
    try {
      result = await Bowden.request(method, path, body);
    } catch (error) {
      say(`The server did not answer (${error.message}): try again.`, true);
      return null;
    }
    if (result.refused) { onRefused(); }
    if (!result.ok) {
      say(result.data.error || `refused (HTTP ${result.status})`, true);
      return null;
    }
    return result.data;
  }

  function registration() {
    const body = {
      participant: $("reg-participant").value.trim(),
      height_m: $("reg-height").value, mass_kg: $("reg-mass").value, sex: $("reg-sex").value,
      arm_side: $("reg-arm").value, hand_load_kg: $("reg-load").value,
    };
    if ($("reg-age").value !== "") { body.age_years = $("reg-age").value; }
    return body;
  }

  async function register(event) {
    event.preventDefault();
    const data = await call("POST", "/api/participants", registration());
    if (data) {
      say(data.registered ? `${data.participant} registered.` : `${data.participant} was registered already.`);
      document.dispatchEvent(new CustomEvent("bowden-registered"));  // the trial form reads the registry
    }
  }

  async function openSession() {
    const body = { participant: $("reg-participant").value.trim() };
    if ($("reg-seed").value !== "") { body.seed = Number($("reg-seed").value); }
    const data = await call("POST", "/api/sessions", body);
    if (data) {
      say(`Session ${data.session_id} of ${data.participant.participant}: ${data.finished ? "complete" : "ready"}.`);
      show(data);
    }
  }

  async function startNext() {
    if (!status) { return; }
    $("start-next").disabled = true;
    const data = await call("POST", `/api/sessions/${status.session_id}/next`, {});
    if (data) { say(`Trial ${data.trial_id} running.`); } else { $("start-next").disabled = false; }
  }

  async function decide(kind, position) {
    const reason = $("decision-reason").value.trim();
    if (reason.length < 3) {
      say(`${kind === "redo" ? "Redo" : "Skip"}: give the reason first (3 characters or more).`, true);
      $("decision-reason").focus();
      return;
    }
    const data = await call("POST", `/api/sessions/${status.session_id}/${kind}`, { position, reason });
    if (data) {
      $("decision-reason").value = "";
      say(kind === "redo" ? `Trial ${position} will run again.` : `Trial ${position} skipped.`);
      show(data);
    }
  }

  function label(condition) {
    const step = status.steps.find((s) => s.condition === condition);
    return step ? step.label : condition;
  }

  function row(step) {
    const tr = document.createElement("tr");
    tr.className = `state-${step.state}`;
    const attempts = step.attempts.filter((a) => a.status !== "completed" && a.status !== "running")
      .map((a) => `trial ${a.trial_id} ${a.status}${a.reason ? `: ${a.reason}` : ""}`);
    const state = step.state + (step.skip_reason ? ` (${step.skip_reason})` : "")
      + (attempts.length ? ` — ${attempts.join("; ")}` : "");
    for (const text of [step.position, step.label, step.speed, state, step.trial_id ?? "–"]) {
      const td = document.createElement("td");
      td.textContent = String(text);
      tr.append(td);
    }
    const actions = document.createElement("td");
    const canRedo = step.state === "done" || (step.state === "pending" && attempts.length > 0
      && step.attempts[step.attempts.length - 1].status === "stopped");
    if (canRedo) { actions.append(button("Redo", "redo", step.position)); }
    if (step.state === "pending") { actions.append(button("Skip", "skip", step.position)); }
    tr.append(actions);
    return tr;
  }

  function button(text, kind, position) {
    const b = document.createElement("button");
    b.type = "button";
    b.className = "small";
    b.textContent = text;
    b.dataset.action = kind;
    b.dataset.position = String(position);
    b.setAttribute("aria-label", `${text} trial ${position}`);
    b.addEventListener("click", () => decide(kind, position));
    return b;
  }

  function show(data) {
    if (!data || data.session_id === null || data.session_id === undefined) { return; }
    status = data;
    const p = data.participant;
    $("reg-participant").value = p.participant;
    const order = data.condition_order.map(label).join(" → ");
    $("plan-summary").textContent = `${p.participant}: session ${data.session_id}, `
      + `${data.order_rule === "latin_square" ? `Latin square row ${data.sequence + 1}` : `random order, seed ${data.seed}`}`
      + ` — ${order}`;
    const body = $("plan").querySelector("tbody");
    body.replaceChildren(...data.steps.map(row));
    const next = data.steps.find((s) => s.position === data.next);
    $("next-box").hidden = false;
    if (data.running !== null) {
      const running = data.steps.find((s) => s.position === data.running);
      $("next-text").textContent = `Running: trial ${running.position} of ${data.progress.total} — ${running.label} at ${running.speed}`;
    } else if (next) {
      $("next-text").textContent = `Next: trial ${next.position} of ${data.progress.total} — ${next.label} at ${next.speed}`
        + `, ${next.repetitions} repetition${next.repetitions > 1 ? "s" : ""}`;
    } else {
      $("next-text").textContent = "The plan is complete.";
    }
    $("start-next").disabled = !next || data.running !== null || Bowden.busy();
    const done = data.progress.done + data.progress.skipped;
    $("progress").textContent = `Progress: ${done} of ${data.progress.total} trials`
      + (data.progress.skipped ? ` (${data.progress.skipped} skipped)` : "");
    const due = $("questionnaire-due");
    due.hidden = !data.questionnaire_due;
    if (data.questionnaire_due) {
      const link = `/questionnaire#participant=${p.participant}&condition=${data.questionnaire_due}`;
      due.replaceChildren(`Questionnaires due after “${label(data.questionnaire_due)}”: `);
      const a = document.createElement("a");
      a.href = link;
      a.target = "_blank";
      a.id = "questionnaire-due-link";
      a.textContent = "open the questionnaire";
      due.append(a);
    }
    breakBase = data.break ? { ...data.break, at_ms: performance.now() } : null;
    tick();
  }

  function tick() {
    const box = $("break-timer");
    box.hidden = breakBase === null;
    if (breakBase === null) { return; }
    const elapsed = breakBase.elapsed_s + (performance.now() - breakBase.at_ms) / 1000;
    const clock = (s) => `${Math.floor(s / 60)}:${String(Math.floor(s % 60)).padStart(2, "0")}`;
    const over = elapsed >= breakBase.length_s;
    box.textContent = `Break after “${label(breakBase.condition)}”: ${clock(elapsed)} of ${clock(breakBase.length_s)}`
      + (over ? " — break over" : "");
    box.classList.toggle("over", over);
  }

  function init(refused) {
    onRefused = refused;
    $("register-form").addEventListener("submit", register);
    $("open-session").addEventListener("click", openSession);
    $("start-next").addEventListener("click", startNext);
    setInterval(tick, 1000);
  }

  async function reload() {
    const data = await call("GET", "/api/sessions/current");
    if (data) { show(data); }
  }

  return { init, show, reload, current: () => status };
})();
