// mocapdb pages: every uncaught error and unhandled rejection written into the page's #errors list (and
// counted in <body data-errors>), so a headless browser's DOM shows them. Inlined before the page's script.
"use strict";
(function () {
  function reportError(text) {
    const list = document.getElementById("errors");
    const li = document.createElement("li");
    li.textContent = text;
    list.appendChild(li);
    document.body.dataset.errors = String(list.children.length);
  }
  window.addEventListener("error", (e) => reportError(`${e.message} (${e.filename}:${e.lineno})`));
  window.addEventListener("unhandledrejection", (e) =>
    reportError(`unhandled rejection: ${e.reason && e.reason.stack ? e.reason.stack : e.reason}`));
})();
