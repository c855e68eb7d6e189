"""The FMU builder: strict compile, cache, packaging, and the C <-> Python variable tables."""

import re
import zipfile
from importlib import resources

import pytest

from pushtrain.fmu import FmuBuildError, build_fmu
from pushtrain.fmu.variables import ARRAYS, SCALARS


def _c_enum(name: str) -> dict[str, int]:
    header = (resources.files("pushtrain.fmu") / "src" / "model.h").read_text()
    body = re.search(r"enum %s \{(.*?)\};" % name, header, re.S).group(1)
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.S)
    return {k.strip(): int(v) for k, v in re.findall(r"(\w+)\s*=\s*(\d+)", body)}


def test_c_value_references_mirror_the_python_table():
    scalars = _c_enum("ScalarVr")
    blocks = _c_enum("Block")
    assert scalars == {f"vr_{v.name}": v.vr for v in SCALARS}
    assert blocks == {f"blk_{b.name}": b.block for b in ARRAYS}


def test_strict_build_with_werror_packages_sources_and_binary(tmp_path, monkeypatch):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    out = build_fmu(2, tmp_path / "TT2.fmu", strict=True)
    with zipfile.ZipFile(out) as zf:
        names = set(zf.namelist())
    assert "modelDescription.xml" in names
    assert "binaries/linux64/TrailerTrain.so" in names
    for src in ("sources/model.c", "sources/chain.c", "sources/forces.c", "sources/fmi2.c",
                "sources/model.h", "sources/build_config.h"):
        assert src in names
    assert not any(n.startswith("sources/fmi2Function") for n in names), "FMI headers vendored"
    cached = list((tmp_path / "cache" / "fmu").glob("*.fmu"))
    assert len(cached) == 1
    mtime = cached[0].stat().st_mtime_ns
    build_fmu(2, tmp_path / "again.fmu", strict=True)  # cache hit: no rebuild
    assert cached[0].stat().st_mtime_ns == mtime
    assert not list(tmp_path.glob(".*.part")), "partial files left behind"


@pytest.mark.parametrize("bad", [0, 51, -1, 2.5, "3", True])
def test_out_of_range_n_is_refused_with_the_value(bad):
    with pytest.raises(FmuBuildError, match=re.escape(repr(bad)) if not isinstance(bad, int) or isinstance(bad, bool) else str(bad)):
        build_fmu(bad)
