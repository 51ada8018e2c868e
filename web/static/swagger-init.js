/* Starts Swagger UI on /docs (no inline script: the CSP allows only our own files). Writes tried
 * from the page with the session cookie carry the session's CSRF token, as the API requires;
 * with a key given under "Authorize" the Bearer header is used instead. */
(function () {
  "use strict";

  var root = document.getElementById("swagger-ui");
  var meta = document.querySelector('meta[name="hmsm-csrf"]');
  var csrf = meta ? meta.getAttribute("content") : "";

  function withCsrf(request) {
    if (csrf && !request.headers.Authorization) { request.headers["X-CSRF-Token"] = csrf; }
    return request;
  }

  window.ui = window.SwaggerUIBundle({
    url: root.getAttribute("data-openapi-url"),
    dom_id: "#swagger-ui",
    layout: "BaseLayout",
    deepLinking: true,
    presets: [window.SwaggerUIBundle.presets.apis,
              window.SwaggerUIBundle.SwaggerUIStandalonePreset],
    requestInterceptor: withCsrf
  });
})();
