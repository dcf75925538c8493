"""The browser page of ``fuzzyservo app``: tune by looking (docs/app.md).

:mod:`.settings` and :mod:`.latest` need numpy only; :mod:`.page` and :mod:`.server` need
Panel (the ``app`` extra) and are imported by the command, never here.
"""

from .latest import Latest, LatestStats
from .settings import PAGE_RUN, PHYSICAL, PageRun, PageSettings, Physical, error_line, run_page

__all__ = ["PAGE_RUN", "PHYSICAL", "Latest", "LatestStats", "PageRun", "PageSettings", "Physical",
           "error_line", "run_page"]
