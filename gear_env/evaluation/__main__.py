"""``python -m gear_env.evaluation``: the steady reward map (:func:`gear_env.cli.steady.main`)."""

from __future__ import annotations

from ..cli.steady import main

if __name__ == "__main__":
    raise SystemExit(main())
