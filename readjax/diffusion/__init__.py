"""SDEs and samplers as pure functions and ``lax.scan`` loops.

* :mod:`readjax.diffusion.irsde` — the mean-reverting (IR-)SDE of METHOD.md section 5;
* :mod:`readjax.diffusion.refine` — READ's cold-diffusion refinement loop (section 8).
"""

from readjax.diffusion import irsde
from readjax.diffusion.refine import refine

__all__ = ["irsde", "refine"]
