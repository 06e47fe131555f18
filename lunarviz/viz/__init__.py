"""PyVista views: the only part of lunarviz that imports PyVista (loaded on first use).

Nothing here runs at import: :func:`lunarviz.viz.render_window.choose_render_window` is called
when a plotter is made.
"""
