"""``python -m pmwm_bench ...`` is ``pmwm bench ...``."""

from .cli import main

raise SystemExit(main())
