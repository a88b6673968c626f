"""plenodecode.report: self-contained HTML reports.

* :mod:`.html` -- page, tables, notes and matplotlib figures inlined as base64 PNG; atomic writing.
* :mod:`.calibration` -- :func:`~plenodecode.report.calibration.write_calibration_report`.
* :mod:`.batch` -- the index page of a batch run.
* :mod:`.lightfield_page` -- the interactive page of a light field (``plenodecode export --format html``).

Submodules are imported on demand (matplotlib is only loaded when a report is written).
"""
