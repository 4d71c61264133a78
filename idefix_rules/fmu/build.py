"""Build the rover FMU from its C sources for the current platform, cached by source hash.

The sources ship inside the package (``idefix_rules.fmu_sources``, the repository's ``fmu/``).
The build compiles them with the system C compiler (``$CC``, else ``cc``/``gcc``/``clang``)
against fmpy's FMI 2.0 headers, or, when no compiler is on the path, through fmpy's CMake
project (:func:`fmpy.build.build_platform_binary`). The ``.fmu`` lands in
``$IDEFIX_CACHE`` (default ``~/.cache/idefix-rules``) as ``idefix_rover-<hash>.fmu``: written
to a temporary file, then renamed, so concurrent builds are safe.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import zipfile
from importlib import resources
from pathlib import Path

from idefix_rules.errors import InfrastructureError
from idefix_rules.files import cache_root

MODEL_IDENTIFIER = "idefix_rover"
_SOURCE_SUFFIXES = (".c", ".h")


def source_dir() -> Path:
    """Directory holding modelDescription.xml and sources/ (installed package or checkout)."""
    try:
        packaged = Path(str(resources.files("idefix_rules.fmu_sources") / MODEL_IDENTIFIER))
        if (packaged / "modelDescription.xml").is_file():
            return packaged
    except (ModuleNotFoundError, TypeError):
        pass
    checkout = Path(__file__).resolve().parents[2] / "fmu" / MODEL_IDENTIFIER
    if (checkout / "modelDescription.xml").is_file():
        return checkout
    raise InfrastructureError("rover FMU sources not found (idefix_rules.fmu_sources or fmu/)")


# No floating-point contraction (no fused multiply-add where the sources write a product and
# a sum; GCC's default in ISO C mode, not Clang's, and it matters where the processor has an
# FMA instruction, as on aarch64), so the optimisation level changes the speed, never a
# result's bits: -O3 gives the example's results file bit for bit as -O2 did, 1 to 6 %
# faster (docs/rover-model.md, "Build"). Part of the source hash: a new flag builds the FMU
# again.
CFLAGS = ("-std=c99", "-O3", "-ffp-contract=off")


def cache_dir() -> Path:
    return cache_root() / "fmu"


def _source_files(src: Path) -> list[Path]:
    files = [src / "modelDescription.xml"]
    files += sorted(p for p in (src / "sources").iterdir() if p.suffix in _SOURCE_SUFFIXES)
    files += sorted(src.glob("*.json"))
    return files


def source_hash(src: Path | None = None) -> str:
    """sha256 over the FMU's sources, the platform, the compiler choice and its flags."""
    import fmpy

    src = src or source_dir()
    digest = hashlib.sha256()
    for path in _source_files(src):
        digest.update(path.relative_to(src).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    digest.update(f"{fmpy.platform}|{_compiler() or 'cmake'}|{' '.join(CFLAGS)}".encode())
    return digest.hexdigest()


def _compiler() -> str | None:
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    return None


def _fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def _compile(unzipdir: Path) -> None:
    """Put the platform binary into ``unzipdir/binaries/<platform>/``."""
    import fmpy

    compiler = _compiler()
    if compiler is None or fmpy.system == "windows":
        from fmpy.build import build_platform_binary

        try:
            build_platform_binary(unzipdir)
        except (OSError, RuntimeError, subprocess.CalledProcessError) as failure:
            # no C compiler, no cmake, or cmake found no compiler (its exit status)
            raise InfrastructureError(
                f"building the rover FMU needs a C compiler (cc, gcc or clang; or $CC): "
                f"none was found, and fmpy's cmake build failed too ({failure})") from None
        return
    target = unzipdir / "binaries" / fmpy.platform
    target.mkdir(parents=True, exist_ok=True)
    sources = sorted(str(p) for p in (unzipdir / "sources").glob("*.c"))
    command = [compiler, *CFLAGS, "-fPIC", "-shared", "-fvisibility=default",
               f"-I{_fmi_headers()}", f"-I{unzipdir / 'sources'}", *sources,
               "-o", str(target / (MODEL_IDENTIFIER + fmpy.sharedLibraryExtension)), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise InfrastructureError(f"building the rover FMU failed ({' '.join(command[:2])} ...):\n"
                                  f"{result.stderr.strip()}")


def build_fmu(force: bool = False, output: Path | None = None) -> Path:
    """Build (or find in the cache) the rover FMU and return the path of the ``.fmu``."""
    src = source_dir()
    target = output or cache_dir() / f"{MODEL_IDENTIFIER}-{source_hash(src)[:16]}.fmu"
    if target.is_file() and not force:
        return target
    try:
        return _built(src, target)
    except OSError as failure:  # a cache folder this user cannot write, a full disk
        raise InfrastructureError(
            f"building the rover FMU into {target.parent} failed: {failure.strerror or failure}"
            f"; the FMU needs a writable folder: point IDEFIX_CACHE at one "
            f"(docs/operations.md, \"The cache folder\")") from None


def _built(src: Path, target: Path) -> Path:
    """Build the FMU of the sources ``src`` into ``target``."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="idefix-fmu-") as tmp:
        unzipdir = Path(tmp) / "fmu"
        (unzipdir / "sources").mkdir(parents=True)
        for path in _source_files(src):
            shutil.copyfile(path, unzipdir / path.relative_to(src))
        _compile(unzipdir)
        fd, partial = tempfile.mkstemp(prefix=target.name, suffix=".part", dir=target.parent)
        os.close(fd)
        try:
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
                for path in sorted(unzipdir.rglob("*")):
                    if path.is_file():
                        archive.write(path, path.relative_to(unzipdir).as_posix())
            # mkstemp's file is this user's alone (0600); the FMU is read by whoever the
            # umask lets read a new file (CI runners, Dask workers of another account)
            os.chmod(partial, 0o666 & ~_umask())
            os.replace(partial, target)
        finally:
            if os.path.exists(partial):
                os.unlink(partial)
    return target


def _umask() -> int:
    """This process's umask (read by setting it and back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def default_fmu_path() -> Path:
    """The built-in rover FMU, built on first use."""
    return build_fmu(force=False)
