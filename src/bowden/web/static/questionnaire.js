// Questionnaires between conditions: the form is built from /api/questionnaires/schema (one source
// of the sites and scales, on the server) and sent as JSON with the session token.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const message = $("message");
  // The console's prompt links here with the participant and the condition just completed.
  const given = new URLSearchParams(location.hash.slice(1));

  Bowden.tokenField($("token"), $("token-box"));

  function say(text, isError) {
    message.textContent = text;
    message.classList.toggle("error", Boolean(isError));
  }

  function element(tag, attributes, text) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attributes || {})) {
      node.setAttribute(key, value);
    }
    if (text !== undefined) { node.textContent = text; }
    return node;
  }

  // One row of radio buttons low..high named `name`, with the scale's verbal anchors as titles.
  function scaleRow(name, label, scale) {
    const row = element("div", { class: "scale-row", role: "radiogroup", "aria-label": label });
    row.append(element("span", { class: "scale-label" }, label));
    const choices = element("span", { class: "scale-choices" });
    for (let value = scale.low; value <= scale.high; value += 1) {
      const id = `${name}-${value}`;
      const input = element("input", { type: "radio", name, id, value: String(value), required: "" });
      const anchor = scale.anchors[String(value)];
      const text = element("label", { for: id, title: anchor || "" }, String(value));
      choices.append(element("span", { class: "choice" }));
      choices.lastChild.append(input, text);
    }
    row.append(choices);
    return row;
  }

  function anchorsLine(scale) {
    return Object.entries(scale.anchors).map(([value, words]) => `${value} = ${words}`).join(" · ");
  }

  function build(schema) {
    for (const c of schema.conditions) {
      $("condition").append(new Option(`${c.label} (${c.id})`, c.id));
    }
    for (const key of ["nordic", "fatigue"]) {
      const section = schema[key];
      const box = $(key);
      box.append(element("legend", {}, section.title));
      box.append(element("p", { class: "hint" }, anchorsLine(section)));
      for (const item of section.items) {
        box.append(scaleRow(`${key}.${item.id}`, item.label, section));
      }
    }
    const borg = schema.borg_rpe;
    const box = $("borg_rpe");
    box.append(element("legend", {}, borg.title));
    box.append(element("p", { class: "hint" }, anchorsLine(borg)));
    const list = element("div", { class: "borg", role: "radiogroup", "aria-label": borg.title });
    for (let value = borg.low; value <= borg.high; value += 1) {
      const id = `borg_rpe-${value}`;
      const line = element("div", { class: "borg-line" });
      line.append(element("input", { type: "radio", name: "borg_rpe", id, value: String(value), required: "" }));
      line.append(element("label", { for: id }, `${value}  ${borg.anchors[String(value)] || ""}`));
      list.append(line);
    }
    box.append(list);
  }

  function answers(form) {
    const body = { participant: $("participant").value.trim(), condition: $("condition").value,
                   nordic: {}, fatigue: {}, replace: $("replace").checked };
    if ($("exception").value.trim() !== "") { body.exception = $("exception").value.trim(); }
    for (const input of form.querySelectorAll("input[type=radio]:checked")) {
      const [section, item] = input.name.split(".");
      if (item === undefined) { body[section] = Number(input.value); }
      else { body[section][item] = Number(input.value); }
    }
    return body;
  }

  $("questionnaire-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    const form = event.target;
    const result = await Bowden.request("POST", "/api/questionnaires", answers(form));
    if (result.ok) {
      say(`Stored ${result.data.stored} answers of ${result.data.participant} after ${result.data.condition}.`);
      for (const input of form.querySelectorAll("input[type=radio]:checked")) { input.checked = false; }
      $("replace").checked = false;
      $("exception").value = "";
    } else {
      say(result.data.error || `refused (HTTP ${result.status})`, true);
      if (result.refused) { Bowden.tokenRefused($("token"), $("token-box")); }
    }
  });

  fetch("/api/questionnaires/schema").then((r) => r.json()).then((schema) => {
    build(schema);
    if (given.get("participant")) { $("participant").value = given.get("participant"); }
    if (given.get("condition")) { $("condition").value = given.get("condition"); }
  });
})();
