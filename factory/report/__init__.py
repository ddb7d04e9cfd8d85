"""``stage=report``: one self-contained HTML page about a run, ``<run_dir>/report.html``.

The report reads the run directory's files and never imports a stage:

* :mod:`factory.report.collect` reads the run into typed dataclasses (:class:`RunData`),
  defensively: a file it cannot use is skipped with a note shown on the page;
* :mod:`factory.report.media` makes thumbnails and turns images into data URIs or files under
  ``report_files/``; :mod:`factory.report.gifs` makes GIFs from recorded frames and videos;
* :mod:`factory.report.charts` draws inline SVG charts; :mod:`factory.report.markdown_html`
  renders the dataset card; :mod:`factory.report.page` writes the page;
* :mod:`factory.report.stage` is ``run(ctx)``.
"""

from __future__ import annotations

from factory.report.collect import RunData, collect_run

__all__ = ["RunData", "collect_run"]
