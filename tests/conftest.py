import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(autouse=True, scope="session")
def _torch_caches_under_tmp_path(tmp_path_factory):
    """torch writes its inductor cache to ``<system temp>/torchinductor_<user>`` unless told otherwise."""
    mp = pytest.MonkeyPatch()
    mp.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path_factory.mktemp("torchinductor")))
    yield
    mp.undo()


@pytest.fixture(autouse=True)
def _sb3_logs_under_tmp_path(tmp_path, monkeypatch):
    """Tests write only under tmp_path: stable-baselines3 models made without a log folder (``PPO(...)``,
    ``learn()`` without TensorBoard) log to ``$SB3_LOGDIR``, else to ``<system temp>/SB3-<date>``."""
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3_logs"))
