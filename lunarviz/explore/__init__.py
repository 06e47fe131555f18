"""The explorer (``lunarviz explore``): a scene's state, the work it needs off the window's thread,
its picture, and the browser app.

* :mod:`~lunarviz.explore.state`: what is explored and shown (:class:`~lunarviz.explore.state.ExploreState`),
  saved as JSON and read back by ``render --state`` and ``sweep --state``;
* :mod:`~lunarviz.explore.engine`: the worker that computes a state's numbers and picture, a first
  (cheap) one and a converged one, newer requests superseding older ones, with a bounded cache and
  a background pass over the slider's range;
* :mod:`~lunarviz.explore.picture`: the picture of a state (the Moon, its earthshine, the light
  paths, the BRDF map, the curves against θ or time with the state marked, the numbers);
* :mod:`~lunarviz.explore.web_app`: the controls and the picture in a browser or a notebook (trame).
"""
