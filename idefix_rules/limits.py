"""How large an input file may be: larger ones are refused at once (exit 2), before any of it
is read, so a damaged or generated file cannot exhaust memory or time. Also the most runs a path
may have and the largest seed (the campaign schema and the command line both check them, and
the command line's help names them without importing the schema).

The limits are far above what the files are for (the operations rulebook is 7 kB, a campaign
3 kB) and below what parses in a few seconds; what is accepted is parsed in time linear in its
size. ``docs/operations.md`` lists them.
"""

from __future__ import annotations

from pathlib import Path

from idefix_rules.errors import Diagnostic, Span, UserInputError, error

MAX_RULEBOOK_BYTES = 128 * 1024  # 18 times the operations rulebook
MAX_RULEBOOK_LINE = 20_000  # characters; the formatter writes lines of at most 100
MAX_CAMPAIGN_BYTES = 256 * 1024
MAX_CASE_FILE_BYTES = 1024 * 1024  # about 50 times the operations rulebook's case file
# A terrain file is a short text header (rocks included) and nx*ny float64 heights; the FMU
# reads at most 16 million nodes (fmu/terrain.py MAX_NODES).
MAX_TERRAIN_HEADER_BYTES = 1024 * 1024
MAX_NPY_DEM_BYTES = 16_000_000 * 8 + 64 * 1024
MAX_CSV_DEM_BYTES = 64 * 1024 * 1024

# Monte Carlo runs per path: the paper's campaigns use hundreds; a million already means
# results files of terabytes, so more is refused rather than attempted.
MAX_RUNS = 1_000_000
# Seeds are stored as 64-bit unsigned integers (results.h5, docs/results-format.md).
MAX_SEED = 2**64 - 1
# Worker processes of one campaign: more than any machine has cores; a larger number is a
# typing mistake (each worker is a process holding an FMU instance).
MAX_WORKERS = 1024

# Terrain geometry, in m. A rock is an obstacle the rover meets, not a landform: a semi-axis
# over 1 km makes a hill or a crater, which the DEM gives. Heights lie within 100 km of their
# datum, as every planet's surface does (Mars spans about 30 km, from the floor of Hellas to the
# top of Olympus Mons). Far beyond, the squares and differences the obstacle checker and the
# rover model take overflow a double: a collision test of a rock 1e200 m wide was always false.
MAX_ROCK_SEMI_AXIS = 1_000.0
MAX_TERRAIN_HEIGHT = 100_000.0
# A rock's smallest semi-axis (1 mm): a smaller grain is part of the regolith, which the soil
# model represents. The collision check certifies its distances to 0.1 mm (CheckSettings.min_step
# in obstacles/result.py), ten times finer; how deep a point lies inside a rock divides by its
# semi-axes, and a semi-axis of 1e-300 m overflowed that (a traceback after the reference runs).
MIN_ROCK_SEMI_AXIS = 0.001
# The rocks the rover model holds (MAX_ROCKS in fmu/idefix_rover/sources/idefix.h).
MAX_TERRAIN_ROCKS = 4096
# A terrain's width along x and along y (m). The rover model places the rover within 1000 km
# of the terrain's frame origin (its initial.x and initial.y range, parameters.c), so ground
# beyond 2000 km across is ground no run starts on; and a flat map that wide is no body's
# surface (across 2000 km of Mars the sphere falls 150 km below its tangent plane, more than
# MAX_TERRAIN_HEIGHT). Far wider, the count of the rover model's rut grid cells over the
# terrain overflowed (soil.c): the FMU ran out of memory or crashed.
MAX_TERRAIN_EXTENT = 2_000_000.0

RULEBOOK_TOO_LARGE = "E900"
RULEBOOK_LINE_TOO_LONG = "E901"
NOT_A_RULEBOOK = "E902"
CAMPAIGN_TOO_LARGE = "C600"
TERRAIN_TOO_LARGE = "C601"


def size_text(size: int) -> str:
    """``262144`` → ``'256 KiB'``."""
    for unit, scale in (("MiB", 1 << 20), ("KiB", 1 << 10)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size} bytes"


def check_file_size(path: str | Path, limit: int, code: str, what: str) -> None:
    """Refuse a file larger than ``limit`` bytes (a missing file is left to the reader)."""
    try:
        size = Path(path).stat().st_size
    except OSError:
        return
    if size > limit:
        raise UserInputError(too_large(code, what, str(path), size, limit))


def too_large(code: str, what: str, path: str, size: int, limit: int) -> Diagnostic:
    """The diagnostic of an input of ``size`` bytes over its ``limit``: the file's size as the
    limit is written (in bytes where rounding would make them look equal)."""
    size_shown, limit_shown = size_text(size), size_text(limit)
    if size_shown == limit_shown:  # 131073 bytes is not "128 KiB; at most 128 KiB"
        size_shown, limit_shown = f"{size} bytes", f"{limit_shown} ({limit} bytes)"
    return error(code, f"{what} {path} is {size_shown}; at most {limit_shown} is accepted",
                 Span(path), hint="is this the file you meant? (limits: docs/operations.md)")


def check_rulebook_text(text: str, path: str) -> None:
    """Refuse rulebook text that is too large or has an overlong line (stored text and editor
    buffers too). The size is the text's in UTF-8, as a file's is measured before it is read,
    so a buffer and its saved file are refused alike (``°`` is two bytes, an emoji four)."""
    if len(text) > MAX_RULEBOOK_BYTES // 4:  # only then may its UTF-8 be over the limit
        size = len(text.encode("utf-8", "surrogatepass"))
        if size > MAX_RULEBOOK_BYTES:
            raise UserInputError(too_large(RULEBOOK_TOO_LARGE, "rulebook file", path, size,
                                           MAX_RULEBOOK_BYTES))
    line_number, start = 1, 0
    while True:
        end = text.find("\n", start)
        stop = len(text) if end < 0 else end
        if stop - start > MAX_RULEBOOK_LINE:
            raise UserInputError(error(
                RULEBOOK_LINE_TOO_LONG, f"line {line_number} has {stop - start} characters; a "
                f"rulebook line may have at most {MAX_RULEBOOK_LINE}",
                Span(path, line_number, 1),
                hint="split a long expression into named constants or derived values"))
        if end < 0:
            return
        line_number, start = line_number + 1, end + 1
