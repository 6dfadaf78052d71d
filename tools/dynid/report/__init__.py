"""Reports: the identification report as one self-contained HTML page, and its figures.

Takes a model file and runs (and a gap workflow's output); hands on figures (figures, gaps_figures:
matplotlib, loaded only when drawing), tables of parameters against CAD and truth (params) and the page
(page, html). Layer: imports every layer below it, gaps included; only cli and api import it.
"""
