"""The browser dashboard: server-rendered pages (``routes``), plotly figures as pure functions
(``figures``), page view models built from the services (``data``) and live updates by
server-sent events (``events``). Templates and static assets live in the top-level ``web``
package (``web/templates``, ``web/static``)."""

from __future__ import annotations

__all__ = ["routes", "figures", "events", "data"]
