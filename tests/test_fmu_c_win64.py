"""The native FMU's win64 binary, tested, not assumed: the C host of tests/c/host.c, built for win64 with
mingw-w64, runs its checks (ramp, two instances, reset, state, NaN, long run in both drive modes) on
``binaries/win64`` under wine and gives linux64's results bit for bit; with every effect on too.

Needs the Debian packages ``gcc-mingw-w64-x86-64-win32`` and ``wine64`` (``make setup-system`` installs
them when root, as ``make test`` does in CI); without them the wine tests skip naming the package.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import mapsfixture as mf
import pytest
from fmpy.validation import validate_fmu
from lxml import etree
from test_fmu_c import HOST_C
from test_fmu_c_effects import EFFECTS

from solenoid_fmu import cli
from solenoid_fmu import fmu as F
from solenoid_fmu.fmu import native

pytestmark = pytest.mark.fmu

WINE_PACKAGE = "wine64"
N_LONG = 20_000
CHECKS = ("ramp", "two_instances", "reset", "state", "nan", f"long_run {N_LONG} steps")


def wine_command() -> str | None:
    """The wine loader: ``wine64`` or ``wine`` on PATH, else Debian's ``/usr/lib/wine/wine64`` (package
    wine64 alone puts nothing on PATH)."""
    for name in ("wine64", "wine"):
        path = shutil.which(name)
        if path:
            return path
    return "/usr/lib/wine/wine64" if os.access("/usr/lib/wine/wine64", os.X_OK) else None


def wine_env(prefix: Path) -> dict:
    """Environment of a quiet, non-interactive wine in its own prefix (no Mono/Gecko installers, no display)."""
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(WINEPREFIX=str(prefix), WINEDEBUG="-all", WINEDLLOVERRIDES="mscoree,mshtml=")
    return env


def _require_toolchain() -> tuple[str, str]:
    """(mingw-w64 compiler, wine): skips naming the missing Debian package."""
    cc = native.cross_compiler(native.WIN64)
    if cc is None:
        pytest.skip(f"no {native.WIN64.compilers[0]}: install the Debian package {native.WIN64.package} "
                    "(`make setup-system` does it when root)")
    wine = wine_command()
    if wine is None:
        pytest.skip(f"no wine64: install the Debian package {WINE_PACKAGE} (`make setup-system` does it when root)")
    return cc, wine


def _fmu_pair(fmu_path, tmp: Path):
    """Unzip the FMU; build host (linux64) and host.exe (win64) against its headers."""
    unz = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp / "fmu")))
    cc, _ = _require_toolchain()
    flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{unz}/sources", f"-I{HOST_C.parent}"]
    for cmd in ([native.find_compiler(), *flags, "-o", str(tmp / "host"), str(HOST_C), "-ldl", "-lm"],
                [cc, *flags, "-D__USE_MINGW_ANSI_STDIO=1", "-o", str(tmp / "host.exe"), str(HOST_C), "-lm"]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
    return unz


def run_host_pair(fmu_path, tmp: Path, prefix: Path, *, n_long: int = N_LONG, fx: bool = False) -> dict:
    """Run the C host on linux64 (native) and on win64 (under wine, in the wine prefix ``prefix``; one
    wine process for all checks).

    Returns ``{"linux64": (stdout, ramp csv bytes), "win64": (...)}``; asserts both passed every check.
    """
    _, wine = _require_toolchain()
    unz = _fmu_pair(fmu_path, tmp)
    guid = fmpy.read_model_description(str(fmu_path)).guid
    lib = unz / "binaries"
    suffix = ["fx"] if fx else []
    runs = {"linux64": [str(tmp / "host"), str(lib / "linux64" / f"{F.MODEL_IDENTIFIER}.so")],
            "win64": [wine, str(tmp / "host.exe"), str(lib / "win64" / f"{F.MODEL_IDENTIFIER}.dll")]}
    out = {}
    for name, cmd in runs.items():
        csv = tmp / f"ramp_{name}.csv"
        proc = subprocess.run([*cmd, guid, str(csv), str(n_long), *suffix], capture_output=True, text=True,
                              timeout=300, env=wine_env(prefix), stdin=subprocess.DEVNULL)
        assert proc.returncode == 0, f"{name}: {proc.stdout}{proc.stderr[-3000:]}"
        lines = proc.stdout.replace("\r\n", "\n").strip().splitlines()
        assert lines[-1] == "ok all", f"{name}: {proc.stdout}"
        for check in CHECKS:
            assert f"ok {check}" in lines, f"{name}: no 'ok {check}' in {lines}"
        out[name] = (lines, csv.read_bytes())
    return out


def _digests(lines) -> dict:
    return dict(line.split() for line in lines if line.startswith("digest_"))


def _ns(lines, key) -> float:
    return float(next(line.split()[1] for line in lines if line.startswith(f"{key} ")))


@pytest.fixture(scope="module")
def wine_prefix(tmp_path_factory):
    """One wine prefix for the module (wine creates it on first start: ~8 s)."""
    return tmp_path_factory.mktemp("wine") / "prefix"


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mf.write_maps(tmp_path_factory.mktemp("win64_maps") / "synthetic", G_eddy_S=0.02)


@pytest.fixture(scope="module")
def fmu_path(maps_dir, tmp_path_factory):
    return F.build_fmu(maps_dir, tmp_path_factory.mktemp("win64_fmu") / "synthetic.fmu", backend="c")


def test_native_fmu_holds_linux64_and_win64_binaries(fmu_path):
    if native.cross_compiler(native.WIN64) is None:
        pytest.skip(f"no {native.WIN64.compilers[0]}: install the Debian package {native.WIN64.package} "
                    "(`make setup-system` does it when root)")
    with zipfile.ZipFile(fmu_path) as zf:
        names = set(zf.namelist())
        root = etree.fromstring(zf.read("modelDescription.xml"))
    assert {f"binaries/linux64/{F.MODEL_IDENTIFIER}.so", f"binaries/win64/{F.MODEL_IDENTIFIER}.dll",
            "sources/CMakeLists.txt", "sources/solenoid_fmu.c"} <= names
    tool = root.get("generationTool")
    assert re.search(r"linux64: \S*gcc \d", tool) and re.search(r"win64: x86_64-w64-mingw32-gcc\S* \d", tool), tool
    assert validate_fmu(str(fmu_path)) == []


def test_win64_dll_imports_only_kernel32_and_msvcrt(fmu_path, tmp_path):
    cc, _ = _require_toolchain()
    objdump = Path(cc).with_name("x86_64-w64-mingw32-objdump")
    assert objdump.exists(), f"{objdump} comes with {native.WIN64.package} (binutils-mingw-w64-x86-64)"
    with zipfile.ZipFile(fmu_path) as zf:
        dll = zf.extract(f"binaries/win64/{F.MODEL_IDENTIFIER}.dll", tmp_path)
    proc = subprocess.run([str(objdump), "-p", dll], capture_output=True, text=True, timeout=60)
    imports = sorted(re.findall(r"DLL Name: (\S+)", proc.stdout), key=str.lower)
    assert [d.lower() for d in imports] == ["kernel32.dll", "msvcrt.dll"], imports
    exports = set(re.findall(r"\]\s+(fmi2\w+)", proc.stdout))
    assert {"fmi2Instantiate", "fmi2DoStep", "fmi2GetDerivatives", "fmi2SerializeFMUstate"} <= exports


def test_win64_binary_under_wine_passes_the_host_checks_bit_for_bit(fmu_path, tmp_path, wine_prefix):
    runs = run_host_pair(fmu_path, tmp_path, wine_prefix)
    (lin, lin_csv), (win, win_csv) = runs["linux64"], runs["win64"]
    assert lin_csv.count(b"\n") == 2002 and lin_csv == win_csv   # the 2000-step ramp, same bytes
    dl, dw = _digests(lin), _digests(win)
    assert set(dl) == {"digest_voltage", "digest_current"} and dl == dw   # 2 x 20 000 steps, every bit
    print(f"ns per step: linux64 {_ns(lin, 'ns_per_step')}, win64 under wine {_ns(win, 'ns_per_step')}")


def test_win64_binary_with_every_effect_matches_linux64(tmp_path, wine_prefix):
    d = mf.write_maps(tmp_path / "fx", G_eddy_S=0.01)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = EFFECTS
    (d / "maps.json").write_text(json.dumps(meta))
    _require_toolchain()
    fmu = F.build_fmu(d, tmp_path / "fx.fmu", backend="c")
    runs = run_host_pair(fmu, tmp_path / "run", wine_prefix, fx=True)
    (lin, lin_csv), (win, win_csv) = runs["linux64"], runs["win64"]
    assert lin_csv == win_csv and _digests(lin) == _digests(win) and len(_digests(lin)) == 2


def test_export_without_the_cross_compiler_skips_win64_and_says_so(maps_dir, tmp_path, monkeypatch, capsys):
    missing = dataclasses.replace(native.WIN64, compilers=("no-such-x86_64-w64-mingw32-gcc",))
    monkeypatch.setattr(native, "CROSS_TARGETS", (missing,))
    monkeypatch.delenv("CC_WIN64", raising=False)
    out = tmp_path / "linux_only.fmu"
    assert cli.main(["export", str(maps_dir), "-o", str(out), "--backend", "c"]) == 0
    text = capsys.readouterr().out
    assert "binaries: linux64;" in text
    assert "skipped win64: no no-such-x86_64-w64-mingw32-gcc (Debian package gcc-mingw-w64-x86-64-win32" in text
    with zipfile.ZipFile(out) as zf:
        assert not [n for n in zf.namelist() if n.startswith("binaries/win64")]
        assert "win64" not in etree.fromstring(zf.read("modelDescription.xml")).get("generationTool")
