// The console's pre-flight: GET /api/console/preflight runs `bowden check` on the server's suit and
// returns its report ({ok, checks: [{name, ok, message}]}); one line per check, as the command prints.
(() => {
  "use strict";
  const $ = (id) => document.getElementById(id);

  function show(report) {
    const list = $("preflight-list");
    list.replaceChildren();
    for (const check of report.checks) {
      const item = document.createElement("li");
      item.className = check.ok ? "ok" : "fail";
      item.textContent = `${check.ok ? "ok" : "FAIL"} ${check.name}: ${check.message}`;
      list.append(item);
    }
    const failed = report.checks.filter((check) => !check.ok).length;
    $("preflight-summary").textContent = failed === 0
      ? "Every check is ok."
      : `${failed} check${failed === 1 ? "" : "s"} failed: fix ${failed === 1 ? "it" : "them"} before the session.`;
  }

  async function run() {
    const button = $("preflight-run");
    button.disabled = true;
    $("preflight-summary").textContent = "Checking the devices (a few seconds)…";
    try {
      const result = await Bowden.request("GET", "/api/console/preflight");
      if (result.ok) {
        show(result.data);
      } else {
        $("preflight-summary").textContent = result.data.error || `HTTP ${result.status}`;
      }
    } catch (error) {
      $("preflight-summary").textContent = "The server did not answer.";
    } finally {
      button.disabled = false;
    }
  }

  $("preflight-run").addEventListener("click", run);
})();
