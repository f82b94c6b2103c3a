from pathlib import Path

import pytest

from navgym.gnss import load_default_almanac, read_rinex_nav, read_rinex_obs

#: Real data in the project's shared data folder beside the repository (read at test time).
DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data"
RINEX_DIR = DATA / "gnss" / "rinex"
OBS_FILE = RINEX_DIR / "07590920.05o"
NAV_FILE = RINEX_DIR / "07590920.05n"


def _require(path: Path) -> Path:
    if not path.is_file():
        pytest.skip(f"real data file {path} is absent (shared data folder not mounted)")
    return path


@pytest.fixture(scope="session")
def almanac():
    return load_default_almanac()


@pytest.fixture(scope="session")
def nav():
    return read_rinex_nav(_require(NAV_FILE))


@pytest.fixture(scope="session")
def obs():
    return read_rinex_obs(_require(OBS_FILE))
