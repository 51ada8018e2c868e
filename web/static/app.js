/* HMSM dashboard: draws the plotly figures embedded as JSON data blocks and keeps the page
 * current through server-sent events (GET /api/v1/events). No inline script (CSP). */
(function () {
  "use strict";

  var main = document.getElementById("main");
  var status = document.getElementById("live-status");
  var pending = false;
  var timer = null;
  var refreshes = 0;
  var lastRefresh = 0;
  var MIN_INTERVAL_MS = 2000;  /* at most one refetch per 2 s, however busy the fleet */
  var PHONE = window.matchMedia("(max-width: 600px)");  /* app.css's phone layout */

  function drawFigures(root) {
    if (typeof window.Plotly === "undefined") { return; }
    var blocks = root.querySelectorAll("script.figure-data");
    for (var i = 0; i < blocks.length; i++) {
      var target = document.getElementById(blocks[i].getAttribute("data-target"));
      if (!target) { continue; }
      var fig = JSON.parse(blocks[i].textContent);
      var layout = fig.layout || {};
      layout.autosize = true;
      /* on a phone the mode bar covers the chart's title, and a tap shows it anyway */
      window.Plotly.newPlot(target, fig.data || [], layout,
        { responsive: true, displaylogo: false, displayModeBar: !PHONE.matches });
    }
  }

  function purgeFigures(root) {
    if (typeof window.Plotly === "undefined") { return; }
    var figs = root.querySelectorAll(".figure");
    for (var i = 0; i < figs.length; i++) { window.Plotly.purge(figs[i]); }
  }

  function setStatus(text, on) {
    if (!status) { return; }
    status.textContent = text;
    status.classList.toggle("on", !!on);
  }

  function busy() {
    /* Do not replace the page under someone typing in one of its fields. */
    var el = document.activeElement;
    if (!el || !main.contains(el)) { return false; }
    var tag = el.tagName;
    return (tag === "INPUT" || tag === "TEXTAREA" || tag === "SELECT") &&
      !(el.type === "hidden" || el.type === "submit");
  }

  function refresh() {
    timer = null;
    if (busy()) { pending = true; return; }
    pending = false;
    lastRefresh = Date.now();
    var focusedId = document.activeElement && document.activeElement.id;
    fetch(window.location.href, { credentials: "same-origin", cache: "no-store",
                                  headers: { "Accept": "text/html" } })
      .then(function (r) {
        if (!r.ok || r.url.indexOf("/signin") !== -1) { throw new Error("HTTP " + r.status); }
        return r.text();
      })
      .then(function (html) {
        var doc = new DOMParser().parseFromString(html, "text/html");
        var fresh = doc.getElementById("main");
        if (!fresh) { return; }
        purgeFigures(main);
        main.innerHTML = fresh.innerHTML;
        drawFigures(main);
        refreshes += 1;
        document.body.setAttribute("data-refreshes", String(refreshes));
        if (focusedId) {
          var again = document.getElementById(focusedId);
          if (again) { again.focus(); }
        }
        setStatus("live · updated " + new Date().toLocaleTimeString(), true);
      })
      .catch(function () { setStatus("update failed", false); });
  }

  function schedule() {
    if (timer !== null) { return; }
    var wait = Math.max(250, MIN_INTERVAL_MS - (Date.now() - lastRefresh));
    timer = window.setTimeout(refresh, wait);
  }

  function subscribe() {
    var wanted = (main.getAttribute("data-live") || "").split(/\s+/).filter(Boolean);
    if (!wanted.length || typeof window.EventSource === "undefined") {
      setStatus(wanted.length ? "no live updates" : "static page", false);
      return;
    }
    var source = new EventSource("/api/v1/events");
    source.addEventListener("hello", function () { setStatus("live", true); });
    source.onerror = function () { setStatus("reconnecting…", false); };
    wanted.forEach(function (name) { source.addEventListener(name, schedule); });
    window.addEventListener("pagehide", function () { source.close(); });
  }

  main.addEventListener("focusout", function () {
    if (pending) { window.setTimeout(function () { if (pending) { schedule(); } }, 50); }
  });

  document.addEventListener("DOMContentLoaded", function () {
    drawFigures(document);
    if (main && main.hasAttribute("data-live")) { subscribe(); }
  });
})();
