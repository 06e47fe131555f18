"""Named parameter presets of the lunar BRDFs (``--moon-model``).

* ``paper``: the paper's Table 2 (Hapke, Apollo 11 soil 10084 at 750 nm; smooth) and the
  Lambert albedo 0.10 of its Table 5. The default, and what ``lunarviz paper`` uses.
* ``rolo-fit``: each BRDF fitted to the ROLO lunar model's disk reflectance (Kieffer & Stone
  2005 as implemented in rimopy), 400-750 nm band, phase angles 2-96° waxing and waning, zero
  libration; kept in ``lunarviz/data/moon_models.json`` with its provenance (fit residuals and
  uncertainties: the documentation's *Photometry* page).
* ``rolo-fit-map``: the same fit on a Moon carrying the synthetic lunar albedo map
  (:mod:`lunarviz.surfaces.maps`, ``--moon-albedo-map synthetic``), which the preset brings with it
  unless a map is given: its maria make the waxing and waning branches differ, as ROLO's do.
"""

from __future__ import annotations

import json

from lunarviz.caches import memoize
from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.resources import DATA_DIR

DATA = DATA_DIR / "moon_models.json"


@memoize(maxsize=1)
def _fitted() -> dict:
    if not DATA.exists():
        return {}
    return json.loads(DATA.read_text())


def moon_model_names() -> tuple[str, ...]:
    return ("paper", *sorted(_fitted().get("models", {})))


def moon_model_map(model: str) -> str | None:
    """The lunar albedo map a preset was fitted with (``--moon-albedo-map`` syntax), or ``None``."""
    if model == "paper":
        return None
    return _fitted().get("models", {}).get(model, {}).get("moon_albedo_map")


def moon_model_params(model: str, brdf: str) -> dict:
    """Parameters of ``brdf`` in preset ``model`` (``{}`` for the paper's defaults)."""
    if model == "paper":
        return {}
    models = _fitted().get("models", {})
    if model not in models:
        raise unknown_choice("moon model", model, moon_model_names())
    if brdf not in models[model] or brdf == "moon_albedo_map":
        has = ", ".join(b for b in models[model] if b != "moon_albedo_map")
        raise LunarvizError(f"--moon-model {model!r} has no {brdf!r} parameters (it has {has})")
    return dict(models[model][brdf]["params"])


def spectral_table(model: str, brdf: str) -> dict | None:
    """``{"wavelength_nm": [...], "params": {name: [...]}, ...}``: a preset's band-by-band fit
    (docs: light in colour), or ``None`` (the paper's model, or none kept)."""
    if model == "paper":
        return None
    return _fitted().get("models", {}).get(model, {}).get("spectral", {}).get(brdf)
