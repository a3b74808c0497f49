"""pmwm_bench: the evaluation of pmwm, apart from the library its users install.

The runner of both robustness protocols, the equal-distortion sweep, the published tables they are
compared with, the markdown and the plots. It drives pmwm through its public API only
(``pmwm.embed``, ``pmwm.verify``, ``pmwm.attacks``, ``pmwm.metrics``); no module of pmwm imports it,
and the Blender extension does not carry it. ``pmwm bench`` reaches it through the ``pmwm.commands``
entry point (it needs the bench extra: ``pip install "pmwm[bench]"``).

Modules (imports go one way: cli -> runner, sweep -> markdown, plots -> records, methods, models,
published, protocols, report -> pmwm):

- ``models``     the one catalogue of benchmark meshes, and where they are found
- ``methods``    ``SchemeMethod``: the four methods (pmwm, pmwm-paper, Cho I, Cho II) behind one interface
- ``published``  the paper's Tables 1-4 and Cho et al.'s published BER
- ``protocols``  the attack settings of both protocols and the seed of each attack realisation
- ``records``    trial and distortion records, table cells
- ``runner``     ``run_bench``: both protocols end to end
- ``sweep``      ``run_sweep``: strengths x methods, BER against MRMS, the comparison at equal MRMS
- ``markdown``   the report sections
- ``plots``      the PNGs (matplotlib, imported lazily)
- ``report``     sections of a markdown file, the commit and the machine a section names
- ``cli``        ``main(argv)``: ``pmwm bench`` and ``pmwm bench --sweep``
- ``corpus``     generated shapes in families (organic, cad, scan, thin, open, near-symmetric ones)
- ``split``      the data meshes a reader may be tuned on and those only reported on; fresh seeds
"""

from .methods import SchemeMethod, default_methods
from .models import CATALOGUE, DEFAULT_MODELS, load_model, model_path, resolve
from .runner import run_bench
from .sweep import run_sweep

__all__ = ["CATALOGUE", "DEFAULT_MODELS", "SchemeMethod", "default_methods", "load_model", "model_path",
           "resolve", "run_bench", "run_sweep"]
