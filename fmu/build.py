"""Build the TrailerTrain FMU from the C sources in ``fmu/src``: FMI 2.0 for one n, or FMI 3.0
for every n.

The build renders the generated files (:mod:`.render`: ``modelDescription.xml``, FMI 3.0's
``sources/buildDescription.xml``, ``build_config.h``, ``variables.h`` and ``start_values.h``, so
the C code never retypes the variable table or its start values), lets fmpy's build helper
write the CMake cache for its own ``CMakeLists.txt`` (the FMI headers come from the installed
fmpy), compiles, and zips a
self-contained ``.fmu`` with the binary (``binaries/linux64/`` for FMI 2.0,
``binaries/x86_64-linux/`` for FMI 3.0) and ``sources/`` so other tools can rebuild it. Builds
are cached by a hash of the sources, the FMI version, n and the build options; a cached FMU
that is not a whole zip (a copy cut short, a full disk) is found when the cache is asked
(:func:`cache_damage`) and rebuilt. A cache folder that cannot be made (``PUSHTRAIN_CACHE``
naming a file) is bad input that names ``PUSHTRAIN_CACHE``.

:func:`package_fmu` (compile and zip any model's files) also builds the second model, the
BackwardController FMU (:mod:`.controller`).
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from importlib import resources
from pathlib import Path

from pushtrain.errors import FmuBuildError, FmuInputError
from pushtrain.files import atomic_write

from .render import (
    HEADER_FILES,
    MODEL_IDENTIFIER,
    check_n,
    render_build_config,
    render_build_description,
    render_model_description,
    render_model_description3,
    render_start_values_header,
    render_variables_header,
    source_files,
)
from .variables import MAX_TRAILERS

__all__ = ["FMI_VERSIONS", "build_fmu", "cache_damage", "cached_path", "cache_dir",
           "ready_cache_dir", "usable_cached", "package_fmu"]

log = logging.getLogger(__name__)

FMI_VERSIONS = (2, 3)
BUILD_FORMAT = "3"  # bump when the rendering or packaging changes


def cache_dir() -> Path:
    """Folder of cached FMUs: ``$PUSHTRAIN_CACHE`` or ``~/.cache/pushtrain/fmu``."""
    root = os.environ.get("PUSHTRAIN_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "pushtrain"
    return base / "fmu"


def ready_cache_dir() -> Path:
    """:func:`cache_dir`, made if missing. Raises FmuInputError naming ``PUSHTRAIN_CACHE`` (and
    what stands in the way) when it cannot be made or written."""
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        reason = None if os.access(folder, os.W_OK | os.X_OK) else "it is not writable"
    except OSError as exc:
        reason = exc.strerror or str(exc)
        blocker = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()),
                       None)
        if blocker is not None:
            reason = f"{str(blocker)!r} is a file"
    if reason is None:
        return folder
    root = os.environ.get("PUSHTRAIN_CACHE")
    where = f"PUSHTRAIN_CACHE = {root!r}" if root else "the default FMU cache"
    raise FmuInputError(f"{where}: the FMU cache {str(folder)!r} cannot be made: {reason}; "
                        "allowed: PUSHTRAIN_CACHE naming a folder (made if missing) where files "
                        "can be written")


def cache_damage(path) -> str | None:
    """Why the cached FMU at ``path`` cannot be used (None if it is whole or missing): not a
    zip (cut short), a member that fails its CRC check, no model description or binary."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
            names = zf.namelist()
    except Exception as exc:  # BadZipFile, zlib.error, EOFError, OSError, ...: damaged
        return f"{type(exc).__name__}: {exc}"
    if bad is not None:
        return f"{bad} fails its CRC check"
    if "modelDescription.xml" not in names or not any(n.startswith("binaries/") for n in names):
        return "it holds no model description or no binary"
    return None


def usable_cached(path) -> bool:
    """Whether the cached FMU at ``path`` is there and whole; a damaged one is logged (as a
    warning: it is rebuilt) and is not."""
    path = Path(path)
    damage = cache_damage(path)
    if damage is not None:
        log.warning("the cached FMU %s is damaged (%s); rebuilding it", path, damage)
        return False
    return path.is_file()


def _source_dir():
    return resources.files("pushtrain.fmu") / "src"


def _generated_files(fmi_version: int, n: int | None, guid: str,
                     generated: str | None = None) -> dict[str, bytes]:
    """The rendered files of a build, by their path in the FMU archive."""
    files = {
        "sources/build_config.h": render_build_config(fmi_version, n, guid).encode(),
        "sources/variables.h": render_variables_header(fmi_version).encode(),
        "sources/start_values.h": render_start_values_header().encode(),
    }
    if fmi_version == 2:
        files["modelDescription.xml"] = render_model_description(n, guid, generated)
    else:
        files["modelDescription.xml"] = render_model_description3(guid, generated)
        files["sources/buildDescription.xml"] = render_build_description()
    return files


def _fingerprint(n: int | None, strict: bool, fmi_version: int = 2) -> str:
    digest = hashlib.sha256()
    digest.update(f"format={BUILD_FORMAT};fmi={fmi_version};n={n};strict={strict}".encode())
    src = _source_dir()
    for name in source_files(fmi_version) + HEADER_FILES:
        digest.update(name.encode())
        digest.update((src / name).read_bytes())
    # what the tables render to (variables.py and everything it reads), not the date of a build
    for path, data in sorted(_generated_files(fmi_version, n, "{guid}", "{date}").items()):
        digest.update(path.encode())
        digest.update(data)
    return digest.hexdigest()


def _cmake_env() -> dict:
    """Environment whose PATH finds cmake: the ``cmake`` wheel (comes with fmpy) first."""
    env = dict(os.environ)
    dirs = []
    try:
        import cmake  # the PyPI wheel

        dirs.append(cmake.CMAKE_BIN_DIR)
    except (ImportError, AttributeError):
        pass
    dirs.append(str(Path(sys.executable).parent))
    env["PATH"] = os.pathsep.join(dirs + [env.get("PATH", "")])
    if shutil.which("cmake", path=env["PATH"]) is None:
        raise FmuBuildError(
            "cmake not found: install the 'cmake' wheel (pip install cmake) or a system cmake"
        )
    return env


def _compile(unzipdir: Path, build_dir: Path, strict: bool,
             version_script: Path | None = None) -> None:
    import fmpy
    from fmpy.build import create_cmake_settings

    options = {
        "CMAKE_C_STANDARD:STRING": "99",
        "CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm",
        "CMAKE_C_VISIBILITY_PRESET:STRING": "hidden",
    }
    if strict:
        options["CMAKE_C_FLAGS:STRING"] = "-Werror"
    if version_script is not None and fmpy.system == "linux":
        # export the fmi2 functions only, whatever the sources mark visible
        options["CMAKE_SHARED_LINKER_FLAGS:STRING"] = f"-Wl,--version-script={version_script}"
    create_cmake_settings(unzipdir, build_dir, all_warnings=True, cmake_options=options)
    source_dir = Path(fmpy.__file__).parent / "c-code"
    env = _cmake_env()
    for command in (
        ["cmake", "-S", str(source_dir), "-B", str(build_dir)],
        ["cmake", "--build", str(build_dir), "--target", "install", "--config", "Release"],
    ):
        done = subprocess.run(command, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-40:])
            raise FmuBuildError(f"{' '.join(command[:2])} failed (exit {done.returncode}):\n{tail}")
        warnings = [line for line in done.stderr.splitlines() if "warning:" in line]
        for line in warnings:
            log.warning("compiler: %s", line)


def _build_into(fmi_version: int, n: int | None, target: Path, strict: bool, guid: str) -> None:
    src = _source_dir()
    files = {f"sources/{name}": (src / name).read_bytes()
             for name in source_files(fmi_version) + HEADER_FILES}
    files.update(_generated_files(fmi_version, n, guid))
    package_fmu(files, MODEL_IDENTIFIER, fmi_version, target, strict)


def package_fmu(files: dict[str, bytes], identifier: str, fmi_version: int, target: Path,
                strict: bool = False, version_script: str | None = None) -> None:
    """Compile an FMU from ``files`` (its archive paths: ``modelDescription.xml``, whose source
    file list fmpy's CMake project reads, and ``sources/...``) and zip it, with the binary, into
    ``target`` (written atomically). Any model: the plant and the controller FMU use it.
    ``version_script`` names a linker version script among the files (GNU ld, Linux): the
    symbols the library exports."""
    import fmpy

    with tempfile.TemporaryDirectory(prefix="pushtrain-fmu-") as tmp:
        unzipdir = Path(tmp) / "fmu"
        (unzipdir / "sources").mkdir(parents=True)
        for path, data in files.items():
            (unzipdir / path).parent.mkdir(parents=True, exist_ok=True)
            (unzipdir / path).write_bytes(data)
        build_dir = Path(tmp) / "build"
        build_dir.mkdir()
        script = None if version_script is None else unzipdir / version_script
        _compile(unzipdir, build_dir, strict, script)
        platform = fmpy.platform if fmi_version == 2 else fmpy.platform_tuple
        library = f"{identifier}{fmpy.sharedLibraryExtension}"
        binary = unzipdir / "binaries" / platform / library
        if not binary.is_file():
            raise FmuBuildError(f"the build produced no {binary.relative_to(unzipdir)}")

        def write_zip(partial: Path) -> None:
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
                for path in sorted(unzipdir.rglob("*")):
                    if path.is_file():
                        zf.write(path, path.relative_to(unzipdir).as_posix())

        atomic_write(target, write_zip)


def _cache_entry(n_trailers, fmi_version, strict: bool):
    """(n, description, source fingerprint, cached .fmu path) of a build (see build_fmu)."""
    if isinstance(fmi_version, bool) or fmi_version not in FMI_VERSIONS:
        raise FmuInputError(f"fmi_version = {fmi_version!r}: allowed are 2 and 3")
    if fmi_version == 2:
        n = check_n(n_trailers)
        name, what = f"{MODEL_IDENTIFIER}-n{n}", f"FMI 2.0, n = {n}"
    elif n_trailers is not None:
        raise FmuInputError(
            f"n_trailers = {n_trailers!r} with fmi_version = 3: the FMI 3.0 FMU serves every n "
            f"from 1 to {MAX_TRAILERS}; set its structural parameter n instead")
    else:
        n, name, what = None, f"{MODEL_IDENTIFIER}3", "FMI 3.0, n = 1.." + str(MAX_TRAILERS)
    fingerprint = _fingerprint(n, strict, fmi_version)
    return n, what, fingerprint, cache_dir() / f"{name}-{fingerprint[:16]}.fmu"


def cached_path(n_trailers: int | None = None, *, fmi_version: int = 2,
                strict: bool = False) -> Path:
    """Where :func:`build_fmu` caches this build (whether or not it is there)."""
    return _cache_entry(n_trailers, fmi_version, strict)[3]


def is_built(n_trailers: int | None = None, *, fmi_version: int = 2,
             strict: bool = False) -> bool:
    """Whether :func:`build_fmu` has this build, whole, in its cache (it then costs no
    compilation)."""
    cached = cached_path(n_trailers, fmi_version=fmi_version, strict=strict)
    return cached.is_file() and cache_damage(cached) is None


def build_fmu(n_trailers: int | None = None, output_path=None, *, fmi_version: int = 2,
              strict: bool = False, force: bool = False) -> Path:
    """Build (or take from the cache) a TrailerTrain FMU.

    Parameters
    ----------
    n_trailers : int, optional
        FMI 2.0: the number of trailers, 1 to 50, fixed by the build. FMI 3.0: leave it out; the
        one FMU serves every n (its structural parameter ``n``).
    output_path : path-like, optional
        Where to write the ``.fmu``; by default the cached file itself is returned.
    fmi_version : {2, 3}
        FMI 2.0 Co-Simulation (scalars ``x[0]``, ...) or FMI 3.0 Co-Simulation (arrays).
    strict : bool
        Compile with ``-Werror`` (development builds).
    force : bool
        Rebuild even if the cache has this build.

    Returns
    -------
    pathlib.Path
        The ``.fmu`` file.

    Raises
    ------
    FmuInputError
        ``n_trailers`` out of range or missing (FMI 2.0) or given (FMI 3.0), an unknown
        ``fmi_version``, or a cache folder that cannot be made (:func:`ready_cache_dir`).
    FmuBuildError
        cmake missing, or the compiler failed.
    """
    n, what, fingerprint, cached = _cache_entry(n_trailers, fmi_version, strict)
    if force or not usable_cached(cached):
        ready_cache_dir()
        guid = "{" + str(uuid.UUID(fingerprint[:32])) + "}"
        log.info("building %s (%s) into %s", MODEL_IDENTIFIER, what, cached)
        _build_into(fmi_version, n, cached, strict, guid)
    else:
        log.debug("using cached %s", cached)
    if output_path is None:
        return cached
    out = Path(output_path)
    if out.is_dir():
        out = out / f"{MODEL_IDENTIFIER}.fmu"
    out.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(out, lambda partial: shutil.copyfile(cached, partial))
