"""SDEs and samplers as pure functions and ``lax.scan`` loops.

* :mod:`readjax.diffusion.irsde` — the mean-reverting (IR-)SDE of METHOD.md section 5;
* :mod:`readjax.diffusion.refine` — READ's cold-diffusion refinement loop (section 8);
* :mod:`readjax.diffusion.vpsde` — the VP SDE of the VPSDE baselines, probability-flow ODE and
  reverse-SDE samplers (section 10);
* :mod:`readjax.diffusion.taskspace` — READ-O's task-space samplers (cold diffusion, reverse
  Euler–Maruyama; section 10).
"""

from readjax.diffusion import irsde, taskspace, vpsde
from readjax.diffusion.refine import refine

__all__ = ["irsde", "refine", "taskspace", "vpsde"]
