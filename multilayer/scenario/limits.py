"""Bounds on the size of what a user hands in, checked before anything is built from it.

A YAML text is scanned event by event (PyYAML's parser: no node, no object built) before
it is composed and loaded: its length, the depth of its nesting and the number of nodes
it holds once every alias is expanded are bounded, and an alias inside the node it
refers to (a recursive document) is refused.  An alias costs nothing to parse but is
walked in full by every reader of the data (the line map, the validation, a deep copy):
nine nested aliases of ten (the "billion laughs") make 10^9 nodes of a 1 kB text.
Files (scenarios, sweeps, studies, CSV profiles) are read up to :data:`MAX_FILE_BYTES`
(regular files only: a device or a pipe could be read for ever), a YAML text parsed up
to :data:`MAX_YAML_CHARACTERS`,
and profiles (CSV rows, DEM samples) hold at most :data:`MAX_PROFILE_POINTS` points.
The bounds are far above any scenario (the shipped ones hold a few hundred nodes, the
largest profile a few thousand points) and are listed in docs/reliability.md.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np
import yaml

from multilayer.errors import InputError
from multilayer.scenario.messages import shown

MAX_FILE_BYTES = 64 * 2**20
"""Largest input file read (bytes): scenario, sweep and study YAML files, CSV profiles."""
MAX_YAML_CHARACTERS = 8 * 2**20
"""Longest YAML text (characters; PyYAML parses about 1 MB/s)."""
MAX_DEPTH = 100
"""Deepest nesting of YAML collections (a scenario nests 4 deep)."""
MAX_NODES = 2_000_000
"""Most YAML nodes (scalars and collections), every alias expanded."""
MAX_PROFILE_POINTS = 1_000_000
"""Most points of a profile: rows of a CSV file, samples of a DEM along its polyline."""
MAX_CELLS = 10**9
"""Most cells of a domain (the memory budget refuses far fewer on any machine)."""
MAX_LAYERS = 10**5
"""Most layers (the exact column solve keeps 128 L^2 bytes per thread: 1.3 TB here)."""
MAX_INITIAL_ENTRIES = 1000
"""Most entries of ``initial`` (a shipped scenario holds one to three): building the initial
state takes each entry over every cell and layer, so that 30 000 entries on 10^5 cells
exhaust the memory of a workstation."""
MAX_OUTPUT_TIMES = 10**7
"""Most output times of a run (``time.end / time.output_interval``), also under --force."""
MIN_END = 1e-290
"""Shortest ``time.end`` (s): the output times of a run are at least ``1e-9 time.end``
apart, so every step stays far above the shortest the engine takes (``MIN_STEP`` of
engine/simulation.py, 4.45e-308 s; half of a denormal step is zero)."""
MIN_CELL_SPACINGS = 1024
"""Floats a cell is at least wide at the domain's ends: its edges ``x_min + i dx`` are then
rounded by at most 1/1024 of a cell (cells of 1e-10 m at x = 1e6 m, where floats are
1.16e-10 m apart, would have edges that coincide: a cell of width 0 and its thickness 0/0)."""
MIN_LAYER_THICKNESS = float(np.finfo(float).tiny)
"""Thinnest layer (m) of a column at ``numerics.dry_threshold``, the thinnest a wet column
is: the smallest layer fraction times the dry threshold must be a normal float.  A layer's
velocity is its momentum divided by its thickness, which a layer that underflows there does
not have (a fraction of 5e-324 is 0 m of every column thinner than 1 m)."""
MIN_DENSITY = 1e-100
"""Smallest ``material.density`` and ``material.particle_density`` (kg/m^3).  A dry flow
does not depend on its density (every stress of the built-in laws is the density times a
kinematic quantity): a small collapse gives the run of 1500 kg/m^3 to round-off down to
1e-150 with Drucker-Prager and Jop's mu(I), whereas near 1e-200 its forces and momenta
underflow below what its result's own check accepts, and at 5e-324 the weight is zero.
Real densities (gases included) lie 100 decades above it."""
DEM_WINDOW = 512
"""Pixels a side of a window of a DEM read at once: a DEM is read only around the samples of
its polyline, a window at a time, never whole (a DEM of 20000 x 20000 pixels is 3 GiB of
float64); a GeoTIFF block larger than :data:`MAX_DEM_BLOCK_PIXELS`, which GDAL decodes whole
to read any pixel of it, is refused."""
MAX_DEM_BLOCK_PIXELS = 2**24
"""Largest block (tile or strip) of a DEM's band, in pixels: 128 MiB of float64."""
MAX_DEM_ELEVATION = 1e7
"""Largest magnitude of a DEM's elevation (m), its scale and offset applied: farther than the
Earth's radius (6.4e6 m) from its datum, a pixel holds no terrain but a fill value written
without being declared nodata (GDAL fills float32 rasters with -3.4e38), or a damaged one."""
MAX_STUDY_RUNS = 10**7
"""Most runs a calibration may ask for: ``experiments x (search.population x parameters x
(search.generations + 1) + refine.evaluations x (parameters + 1) + 2 x parameters)``, its
search, refinement and uncertainty at their largest.  Ten million runs of the smallest
scenario (0.1 s each) take 12 days of a core; 10^4 generations of a population of 10^4
over 4 parameters and 3 experiments would ask for 1.2 x 10^9 runs.  A sensitivity
study's ``samples x (parameters + 2)`` runs are at most 3 x 10^6 under
:data:`MAX_DESIGN_VALUES` (65536 samples of 44 parameters)."""
MAX_DESIGN_VALUES = 2**27
"""Values (one a parameter of a run) of a study's design held at once: a Sobol' design of
``samples x (parameters + 2)`` runs, a differential evolution's population of
``population x parameters`` members, each of ``parameters`` values; 1 GiB of float64
(65536 base samples of 399 parameters would take 78 GiB)."""
MAX_ITERATIONS = 10**5
"""Most Newton iterations per column and vertical step (``numerics.max_iterations``): a
column that does not converge takes that many before the run stops (the compiled solve
counts in 64-bit integers, and 10^18 iterations would never end)."""
MIN_TOLERANCE = 1e-14
"""Smallest ``numerics.tolerance``, relative to the velocity scale: velocities of that
scale are resolved to 2.2e-16 and a Newton solve's round-off is some of those (a small
collapse with Jop's mu(I) cannot converge within 2.3e-16 after a few dozen steps, nor within
1e-16 after a few), so that convergence below it is decided by round-off."""


def check_yaml(text: str, where: str, loader: type) -> None:
    """Raise :class:`InputError` naming ``where`` if the YAML ``text`` exceeds the bounds
    of this module; malformed YAML is left to the loader, which names the line."""
    if len(text) > MAX_YAML_CHARACTERS:
        raise InputError(
            f"{where}: {len(text)} characters of YAML; accepted: at most {MAX_YAML_CHARACTERS} (a scenario "
            "file is a few kB; give long profiles as CSV files)"
        )
    sizes: dict[str, int] = {}  # anchor -> nodes of its node, aliases expanded
    open_: list[tuple[str | None, int]] = []  # collections not closed yet: anchor, nodes before them
    counted = 0  # nodes so far, aliases expanded
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                open_.append((event.anchor, counted))
                counted += 1
                if len(open_) > MAX_DEPTH:
                    raise _refused(where, event, f"collections nested more than {MAX_DEPTH} deep")
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                anchor, before = open_.pop()
                if anchor is not None:
                    sizes[anchor] = counted - before
            elif isinstance(event, yaml.ScalarEvent):
                counted += 1
                if event.anchor is not None:
                    sizes[event.anchor] = 1
            elif isinstance(event, yaml.AliasEvent):
                if any(anchor == event.anchor for anchor, _ in open_):
                    raise _refused(where, event, f"the alias *{event.anchor} lies inside its own anchor")
                counted += sizes.get(str(event.anchor), 1)
            if counted > MAX_NODES:
                raise _refused(where, event, f"more than {MAX_NODES} values once its aliases are expanded")
    except yaml.MarkedYAMLError as exc:
        if "maximum nesting depth" in str(exc.problem):  # libyaml's own bound, 1000 deep, met scanning ahead
            raise _refused(where, exc, f"collections nested more than {MAX_DEPTH} deep") from None
    except yaml.YAMLError:
        return  # the loader names the problem and its line


YAML_1_1_LINE_BREAKS = {"\x85": "NEXT LINE", "\u2028": "LINE SEPARATOR", "\u2029": "PARAGRAPH SEPARATOR"}
"""Characters a YAML 1.1 parser (libyaml's, multilayer's) ends a line at, and YAML 1.2, the
``csv`` module and an editor do not (it shows them within the line, or as a mark)."""


def check_line_breaks(text: str, where: str) -> None:
    """:class:`InputError` naming ``where`` and the line and column (lines ended by
    ``\n``, ``\r\n`` or ``\r``, as an editor counts them) of a character of
    :data:`YAML_1_1_LINE_BREAKS` in a YAML text the user writes: the parser ended the line
    there, so that ``name: tiny  # slope 25<U+0085>slope_deg: 40`` set a slope of 40 degrees
    that every reader of the file sees as a comment (U+2028 in a description likewise),
    and each such character shifted the line numbers of every message after it."""
    found = [text.find(c) for c in YAML_1_1_LINE_BREAKS]
    found = [i for i in found if i >= 0]
    if not found:
        return
    at = min(found)
    before = text[:at]
    line = before.count("\n") + before.count("\r") - before.count("\r\n") + 1
    column = at - max(before.rfind("\n"), before.rfind("\r"))
    raise InputError(
        f"{where} (line {line}, column {column}): the character U+{ord(text[at]):04X} "
        f"({YAML_1_1_LINE_BREAKS[text[at]]}), where YAML 1.1 (multilayer's parser) ends a line and an "
        "editor does not; accepted: lines ending at \\n, \\r\\n or \\r only (in a double-quoted string "
        'the character written as an escape, "\\u2028")'
    )


def check_text(text: str, where: str) -> None:
    """:class:`InputError` naming ``where`` for a text that is no Unicode text: a lone
    surrogate, how Python keeps a byte of a command-line argument that is not UTF-8
    (``--set name=$'\\xff'``, U+DC80 to U+DCFF), or half of a UTF-16 pair given from
    Python.  libyaml's parser and the result file's attributes encode every text in UTF-8:
    such a text was a ``UnicodeEncodeError`` with a traceback (a ``--set`` value, a
    ``description`` of a mapping at the end of a run)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        code = ord(text[exc.start])
        what = (
            f"the byte 0x{code - 0xDC00:02X}, which is not UTF-8"
            if 0xDC80 <= code <= 0xDCFF
            else (f"U+{code:04X}, half of a UTF-16 pair")
        )
        raise InputError(
            f"{where}: {shown(text)} holds {what} (character {exc.start + 1}); accepted: text in UTF-8"
        ) from None


PLAIN_VALUES = "finite numbers, strings, booleans, None, and lists and mappings of them"
"""What a scenario given as Python data holds (``multilayer.load`` of a mapping, overrides)."""


def plain_data(value: Any, where: str) -> Any:
    """A copy of ``value``, a scenario or a value given as Python data (``multilayer.load``
    of a mapping), in the types YAML gives: numpy scalars and arrays as numbers and lists,
    tuples as lists.  :class:`InputError` naming ``where`` and the key beyond the bounds of
    a YAML text (nesting, number of values), or holding a text that is not Unicode
    (:func:`check_text`); a structure that holds itself nests without end.  A numpy date or
    duration is no number (``np.timedelta64(5)`` of no unit gives the integer 5), nor a
    masked value (``tolist()`` gives None, which the schema would quote as given), and a
    value that cannot be copied (a generator, an open file) no value of a scenario: all
    are named; an object array of no dimension is the object it holds; other values are
    left to the schema, which names them."""
    count = 0

    def place(path: tuple[Any, ...]) -> str:
        return ".".join(str(k) for k in path[:4]) + (".(...)" if len(path) > 4 else "") or "(top level)"

    def plain(item: Any, path: tuple[Any, ...]) -> Any:
        nonlocal count
        count += 1 + (item.size if isinstance(item, np.ndarray) else 0)
        if len(path) > MAX_DEPTH or count > MAX_NODES:
            raise InputError(
                f"{where}: {place(path)}: more than {MAX_DEPTH} nested collections or {MAX_NODES} "
                f"values; accepted: mappings and lists nested at most {MAX_DEPTH} deep, not holding "
                f"themselves, of at most {MAX_NODES} values"
            )
        at = f"{where}: {place(path)}" if path else where
        if isinstance(item, str):
            check_text(item, at)
        if isinstance(item, Mapping):
            for name in item:
                if isinstance(name, str):
                    check_text(name, f"{where}: {place(path)}: a key")
            return {
                (key.item() if isinstance(key, np.generic) else key): plain(entry, (*path, key))
                for key, entry in item.items()
            }
        if np.ma.isMaskedArray(item) and np.ma.count_masked(item):  # tolist() gives None there
            raise InputError(
                f"{at}: a masked array of {np.ma.count_masked(item)} masked value(s) (a netCDF file's "
                f"fill values, or np.ma.masked), not a number; accepted: {PLAIN_VALUES}"
            )
        if isinstance(item, np.ndarray) and item.dtype.kind not in "mMO":
            return item.tolist()
        if isinstance(item, np.ndarray) and item.ndim == 0 and item.dtype.kind == "O":  # not iterable
            return plain(item[()], path)
        if isinstance(item, np.ndarray) and item.dtype.kind == "O":  # its entries are any object
            return [plain(entry, (*path, index)) for index, entry in enumerate(item)]
        if isinstance(item, (list, tuple)):
            return [plain(entry, (*path, index)) for index, entry in enumerate(item)]
        if isinstance(item, (np.datetime64, np.timedelta64, np.ndarray)):  # an array of them too
            raise InputError(
                f"{at}: {shown(item)} is a numpy date or duration (or an array of them), not a number; "
                f"accepted: {PLAIN_VALUES}"
            )
        if isinstance(item, np.generic):
            return item.item()
        if isinstance(item, (str, bytes, int, float, type(None))):
            return item
        try:  # every reader copies the data: one that cannot be copied is named here
            return copy.deepcopy(item)
        except Exception:  # noqa: BLE001 - whatever its __deepcopy__ or __reduce__ raises
            raise InputError(
                f"{at}: {shown(item)} is not a value of a scenario (it cannot be "
                f"copied); accepted: {PLAIN_VALUES}"
            ) from None

    return plain(value, ())


def _refused(where: str, event: yaml.Event | yaml.MarkedYAMLError, what: str) -> InputError:
    mark = event.problem_mark if isinstance(event, yaml.MarkedYAMLError) else event.start_mark
    line = f" (line {mark.line + 1})" if mark is not None else ""
    return InputError(
        f"{where}{line}: {what}; accepted: a YAML document without an alias inside its own anchor, "
        f"nested at most {MAX_DEPTH} deep, of at most {MAX_NODES} values with its aliases expanded"
    )
