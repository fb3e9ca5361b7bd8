"""An interactive 3-D view of a run: ``python3 -m lgvi.viewer RUN_DIR [--open] [--movie OUT.mp4]``.

Writes ``RUN_DIR/view.html``, one self-contained page that opens offline from
disk (``file://``, no server, no network): three.js (the npm package
``three``: the copy an installed wheel carries in ``lgvi/_three``, else
``web/node_modules`` of the source tree, installed by ``scripts/setup.sh``) is inlined as ES modules behind an import map of
``data:`` URLs, and the trajectory is embedded as base64 float32 (positions
and quaternions; times and diagnostics float64), decimated to at most
``max_frames`` frames and about ``max_bytes`` bytes (the page says so when it
decimates). The CLI's ``lgvi view`` and ``lgvi run --view`` call this module,
and Python calls ``lgvi.view(result_or_dir)``: one code path.

The page exposes ``window.lgviView`` (``ready``, ``frames``, ``times``,
``state(t)``, ``seek(t)``, ``project()``, ...) for tests and for
``--movie``, which renders frames in Debian's headless chromium (through
``web/movie.mjs`` and puppeteer-core) and encodes them with ``ffmpeg``.
Pure Python + numpy (reads runs with ``lgvi.load``).
"""

import argparse
import base64
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

from ._columns import body_of
from ._io import load, load_bodies

#: Frames embedded at most (the page interpolates between them).
MAX_FRAMES = 2000
#: Raw bytes of embedded per-frame data at most (base64 makes it 4/3 of this).
MAX_BYTES = 36_000_000
#: Bins of the small error plots (min/max envelope of every row, not just the embedded frames).
PLOT_BINS = 1000
SETUP_HINT = "run scripts/setup.sh, or: npm ci --prefix web (in the lgvi source tree)"


class ViewError(Exception):
    """Bad input or a missing tool, with a message naming the fix."""


# ---------------------------------------------------------------- geometry

def _quat_of_matrix(m):
    """Scalar-first unit quaternion of a rotation matrix (Shepperd's method)."""
    m = np.asarray(m, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0] * 4
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def inertia_ellipsoid(mass, inertia):
    """(semi-axes (3,), principal-axes quaternion (4,)) of the solid ellipsoid of this mass and inertia.

    A uniform ellipsoid with semi-axes a, b, c has J1 = m (b^2 + c^2) / 5 (and
    cyclically), so a^2 = 5 (J2 + J3 - J1) / (2 m). Moments that violate the
    triangle inequality (``physical = false``) would give a^2 < 0: clamped to
    a thousandth of the largest axis.
    """
    moments, axes = np.linalg.eigh(np.asarray(inertia, dtype=float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    total = moments.sum()
    sq = 5.0 * (total - 2.0 * moments) / (2.0 * mass)
    floor = 1e-6 * max(float(sq.max()), 1e-300)
    return np.sqrt(np.maximum(sq, floor)), _quat_of_matrix(axes)


def _parts(bodies, potential):
    """Per drawn part: (body index, offset in the body frame (3), part quaternion (4), semi-axes (3)),
    and per body the offset of its centre of mass from its reference point (the heavy top's pivot)."""
    rows, com = [], np.zeros((len(bodies), 3))
    chi = np.asarray(potential.get("pivot_to_com", [0.0, 0.0, 0.0]), dtype=float)
    pivot = potential.get("kind") == "heavy-top"
    for b, body in enumerate(bodies):
        balls = body.get("balls") or []
        mass = float(body.get("mass", 1.0))
        if balls:
            rho = np.array([ball["position"] for ball in balls], dtype=float)
            radii = np.array([float(ball.get("radius", 0.0)) for ball in balls])
            extent = float(np.max(np.linalg.norm(rho, axis=1)))
            if not np.any(radii > 0):  # point masses: dots a twentieth of the body's size (a single one: none)
                radii[:] = 0.05 * extent
            for r_, rad in zip(rho, radii):
                rows.append([b, *r_, 1.0, 0.0, 0.0, 0.0, rad, rad, rad])
            continue
        inertia = np.asarray(body["inertia"], dtype=float)
        offset = np.zeros(3)
        if pivot:  # inertia given about the pivot: the ellipsoid is about the centre of mass
            inertia = inertia - mass * (chi @ chi * np.eye(3) - np.outer(chi, chi))
            offset = chi
            com[b] = chi
        axes, q = inertia_ellipsoid(mass, inertia) if np.any(inertia != 0.0) else (np.zeros(3), [1.0, 0, 0, 0])
        rows.append([b, *offset, *q, *axes])
    return np.array(rows, dtype=float).reshape(-1, 11), com


def _size_points(parts, lo, hi):
    """Point bodies (a single point mass, or a mass without inertia) have no size of their own: drawn as
    balls of half the median size of the other parts, or, with nothing else, of a hundredth of the scene's
    extent (1 if the scene is a point)."""
    point = np.all(parts[:, 8:11] == 0.0, axis=1)
    if not np.any(point):
        return
    others = parts[~point, 8:11].max(axis=1)
    extent = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    radius = 0.5 * float(np.median(others)) if len(others) else (0.01 * extent if extent > 0.0 else 1.0)
    parts[point, 8:11] = radius


# ---------------------------------------------------------------- data

def _frames(rows, max_frames, bytes_per_frame, max_bytes):
    """Indices of the embedded rows: every stride-th row (at most k of them), and the last."""
    k = int(min(rows, max_frames, max(2, max_bytes // max(bytes_per_frame, 1))))
    if rows <= k:
        return np.arange(rows)
    stride = -(-(rows - 1) // (k - 1))  # ceil: every stride-th row, evenly spaced in time
    return np.unique(np.append(np.arange(0, rows, stride), rows - 1))


def _envelope(t, values, bins):
    """(t, min, max) of values over `bins` equal groups of rows: every row counts, not only the embedded frames."""
    n = len(t)
    if n <= 2 * bins:
        return t, values, values
    edges = np.linspace(0, n, bins + 1).astype(int)
    lo = np.minimum.reduceat(values, edges[:-1])
    hi = np.maximum.reduceat(values, edges[:-1])
    return t[edges[:-1]], lo, hi


def _b64(array, dtype):
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def _finite(values):
    return [v if np.isfinite(v) else None for v in (float(x) for x in values)]


def _bodies_beside(result):
    """setup.bodies where the run wrote its lists of bodies to a file of their own (summary.json's
    body_lists: beyond 10 000 bodies, or [output] body_lists = "file"); [{}] per body (refused below) where
    there is none."""
    lists = result.summary.get("body_lists")
    if not isinstance(lists, dict):
        return [{}] * result.bodies
    if not lists.get("file") or not result.source:
        raise ViewError("this run kept no lists of bodies (lgvi.simulate of more than 10 000 bodies, or [output] "
                        "body_lists = \"file\", writes no file): view the run folder of lgvi run, or set [output] "
                        "body_lists = \"summary\"")
    try:
        return load_bodies(os.path.dirname(os.fspath(result.source)) or ".")
    except FileNotFoundError as e:  # a trajectory (npz, HDF5: its own summary) away from its folder
        raise ViewError(f"{result.source}: its summary's lists of bodies are in {lists['file']} beside it, which is "
                        f"not there ({e.filename or e})") from None


def page_data(result, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES):
    """The metadata (JSON-able dict) and the base64 arrays the page embeds, from an lgvi Result."""
    summary = result.summary
    setup = summary.get("setup") or {}
    potential = setup.get("potential") or {}
    x, q = result.per_body("x"), result.per_body("q")  # (steps, N, 3), (steps, N, 4) in either layout
    names = list(result.names)
    # One body's own |q| - 1 in the single-body layout; the largest of the bodies' in the long one.
    if result.layout == "single-body":
        quat_err = result.quat_norm_error
    else:
        quat_err = np.max(np.abs(result.quat_norm_error), axis=1)
    # A [body] scenario's body is setup.body (in either layout), a one-body [[bodies]] scenario's setup.bodies.
    if result.layout == "single-body" or "body" in setup:
        bodies = [body_of(summary)]
    else:
        bodies = setup.get("bodies") or _bodies_beside(result)
    if len(bodies) != x.shape[1] or any("inertia" not in b and not b.get("balls") for b in bodies):
        raise ViewError(f"{result.source}: the summary does not describe the bodies (setup.body or setup.bodies "
                        f"with mass, inertia and balls); run it again with this lgvi")
    t = result.t
    rows, n = x.shape[0], x.shape[1]
    idx = _frames(rows, max_frames, n * 7 * 4 + 4 * 8, max_bytes)
    parts, com = _parts(bodies, potential)
    diag = {"energy_error": result.energy_error, "quat_norm_error": quat_err,
            "momentum_error": result.momentum_error}
    extent_pts = x[idx].reshape(-1, 3)
    lo, hi = extent_pts.min(axis=0), extent_pts.max(axis=0)
    # A periodic box: the page wraps each centre of mass into it along the periodic axes (after interpolating
    # the unwrapped path, so that nothing sweeps across the box between frames) and draws its outline; the view
    # frames the box there.
    box = setup.get("box") or {}
    periodic_box = None
    if any(box.get("periodic", ())):
        periodic = np.array(box["periodic"], dtype=bool)
        lower, upper = np.array(box["lower"], dtype=float), np.array(box["upper"], dtype=float)
        lo, hi = np.where(periodic, lower, lo), np.where(periodic, upper, hi)
        periodic_box = {"lower": lower.tolist(), "upper": upper.tolist(), "periodic": periodic.tolist()}
    _size_points(parts, lo, hi)
    size = float(np.max(parts[:, 8:11])) if len(parts) else 0.0
    reach = float(np.max(np.linalg.norm(parts[:, 1:4], axis=1) + parts[:, 8:11].max(axis=1))) if len(parts) else 0.0
    meta = {
        "title": summary.get("scenario") or os.path.basename(os.path.dirname(os.fspath(result.source or ""))) or "run",
        "bodies": n, "names": names if n <= 10000 else None,
        "rows": int(rows), "frames": int(len(idx)), "decimated": bool(len(idx) < rows),
        "completed": bool(summary.get("completed", True)), "error": summary.get("error", ""),
        "potential": {k: v for k, v in potential.items() if isinstance(v, (str, int, float, list))},
        "interaction": (setup.get("interaction") or {}).get("kind", "none"),
        "parts": len(parts), "box": [lo.tolist(), hi.tolist()], "part_size": size, "body_size": reach,
        "periodic_box": periodic_box,
        "max_abs": {k: float(np.max(np.abs(v))) if len(v) else 0.0 for k, v in diag.items()},
        "plots": {},
    }
    for name, values in diag.items():
        pt, plo, phi = _envelope(t, np.asarray(values, dtype=float), PLOT_BINS)
        meta["plots"][name] = {"t": _finite(pt), "lo": _finite(plo), "hi": _finite(phi)}
    arrays = {
        "times": _b64(t[idx], "<f8"),
        "pos": _b64(x[idx], "<f4"),
        "quat": _b64(q[idx], "<f4"),
        "diag": _b64(np.column_stack([np.asarray(v, dtype=float)[idx] for v in diag.values()]), "<f8"),
        "parts": _b64(parts, "<f4"),
        "com": _b64(com, "<f4"),
    }
    return meta, arrays


# ---------------------------------------------------------------- three.js

def _source_dirs():
    """Folders that may hold web/: LGVI_SOURCE_DIR, the source tree recorded by the build, and the ancestors."""
    here = os.path.dirname(os.path.abspath(__file__))
    dirs = []
    if os.environ.get("LGVI_SOURCE_DIR"):
        dirs.append(os.environ["LGVI_SOURCE_DIR"])
    recorded = os.path.join(here, "_source_dir.txt")  # written by the build (src/python/CMakeLists.txt)
    if os.path.isfile(recorded):
        with open(recorded, encoding="utf-8") as f:
            dirs.append(f.read().strip())
    d = here
    while os.path.dirname(d) != d:
        d = os.path.dirname(d)
        dirs.append(d)
    return dirs


def web_dir():
    """The source tree's web/ folder with its node_modules (three, puppeteer-core); ViewError naming the fix."""
    for d in _source_dirs():
        web = os.path.join(d, "web")
        if os.path.isfile(os.path.join(web, "node_modules", "three", "build", "three.module.js")):
            return web
    raise ViewError("three.js is not installed (no web/node_modules/three/build/three.module.js next to the lgvi "
                    f"sources): {SETUP_HINT}")


def three_dir():
    """The folder with three.js's build/ and examples/: the installed package's own copy (lgvi/_three, put
    there by the wheel's build, setup.py) or the source tree's web/node_modules/three."""
    packaged = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_three")
    if os.path.isfile(os.path.join(packaged, "build", "three.module.js")):
        return packaged
    return os.path.join(web_dir(), "node_modules", "three")


def _data_url(text):
    return "data:text/javascript;base64," + base64.b64encode(text.encode("utf-8")).decode("ascii")


def three_importmap():
    """The import map that inlines three.js (three.core.js, three.module.js) and OrbitControls as data: URLs."""
    three = three_dir()

    def read(*path):
        with open(os.path.join(three, *path), encoding="utf-8") as f:
            return f.read()

    module = read("build", "three.module.js")
    # three.module.js imports its core relatively, which a data: URL cannot resolve: name it in the map instead.
    module = module.replace("from './three.core.js'", "from 'three/core'")
    imports = {"three": _data_url(module), "three/core": _data_url(read("build", "three.core.js")),
               "three/addons/OrbitControls.js": _data_url(read("examples", "jsm", "controls", "OrbitControls.js"))}
    return json.dumps({"imports": imports})


# ---------------------------------------------------------------- the page

def _script_json(value):
    """JSON safe inside a <script> element."""
    return json.dumps(value, separators=(",", ":")).replace("</", "<\\/")


def _render(result, max_frames, max_bytes):
    """(the HTML text of the view of a Result, the page's metadata)."""
    meta, arrays = page_data(result, max_frames, max_bytes)
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "viewer.html"), encoding="utf-8") as f:
        template = f.read()
    return (template.replace("/*LGVI_IMPORTMAP*/", three_importmap())
            .replace("/*LGVI_META*/", _script_json(meta))
            .replace("/*LGVI_ARRAYS*/", _script_json(arrays))
            .replace("LGVI_TITLE", f"lgvi view: {meta['title']}".replace("<", "&lt;"))), meta


def render_page(result, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES):
    """The HTML text of the view of a Result."""
    return _render(result, max_frames, max_bytes)[0]


def decimation_note(meta, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES):
    """What the page embeds of the run's rows, when it cannot embed them all ("" when it does)."""
    if not meta["decimated"]:
        return ""
    return (f"lgvi view: {meta['rows']} rows decimated to {meta['frames']} frames (every k-th row and the last; "
            f"the page embeds at most {max_frames} frames and {max_bytes / 1e6:.0f} MB of frame data, --max-frames) "
            f"and interpolates between them")


def _load(source):
    if isinstance(source, (str, bytes, os.PathLike)):
        path = os.fsdecode(source)
        if not os.path.exists(path):
            raise ViewError(f"{path}: no such run folder")
        try:
            return load(path), (path if os.path.isdir(path) else os.path.dirname(path) or ".")
        except FileNotFoundError:
            raise ViewError(f"{path}: no run here (no trajectory.csv, trajectory.npz or trajectory.h5; "
                            f"write one with lgvi run)") from None
    if not hasattr(source, "summary") or not hasattr(source, "t"):
        raise TypeError(f"view: expected a run folder, a trajectory file or an lgvi Result, got {type(source).__name__}")
    return source, None


def _write_view(source, out, max_frames, max_bytes):
    """(the path written, the page's metadata): see write_view."""
    result, folder = _load(source)
    if out is None:
        if folder is None:
            raise ValueError("view: an in-memory result needs out= (a path for the .html file)")
        out = os.path.join(folder, "view.html")
    out = os.fsdecode(out)  # a str, bytes or path-like (pathlib.Path) name
    html, meta = _render(result, max_frames, max_bytes)
    if os.path.exists(out) and not os.path.isfile(out):
        # A device or pipe (--out /dev/stdout): written into; replacing it would put a file in its place.
        with open(out, "w", encoding="utf-8") as f:
            f.write(html)
        return out, meta
    tmp = out + ".tmp"  # a file: never seen half written
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(html)
    os.replace(tmp, out)
    return out, meta


def write_view(source, out=None, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES):
    """Write the view of a run folder, trajectory file or Result to `out` (default RUN_DIR/view.html); the path."""
    return _write_view(source, out, max_frames, max_bytes)[0]


def view(source, out=None, max_frames=MAX_FRAMES, display=True):
    """Write the interactive 3-D view of a run (folder, trajectory file or Result) and return its path.

    In Jupyter (IPython importable and a kernel running) the page is also
    displayed inline in an iframe, if ``display``: one output whose text/html
    is the iframe and whose text/plain (for frontends without HTML) names the
    file. It is published as a raw MIME bundle: IPython's HTML object warns
    on every HTML that starts with an iframe.
    """
    path = write_view(source, out, max_frames)
    if display:
        try:
            from IPython import get_ipython
            from IPython.display import display as show
        except ImportError:
            return path
        shell = get_ipython()
        if shell is not None and type(shell).__name__ == "ZMQInteractiveShell":
            import html as html_escape
            with open(path, encoding="utf-8") as f:
                srcdoc = html_escape.escape(f.read(), quote=True)
            show({"text/html": f'<iframe srcdoc="{srcdoc}" style="width:100%;height:640px;border:0"></iframe>',
                  "text/plain": f"lgvi view: {path}"}, raw=True)
    return path


# ---------------------------------------------------------------- --open and --movie

def open_in_browser(path):
    """Open the page with xdg-open where there is a display; else say where it is. Returns the message."""
    url = "file://" + os.path.abspath(path)
    if (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) and shutil.which("xdg-open"):
        subprocess.Popen(["xdg-open", url], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True)
        return f"lgvi view: opened {url}"
    return f"lgvi view: no display to open a browser on; open {url} in a browser"


def make_movie(html_path, out, seconds=10.0, fps=30, width=1280, height=720):
    """Render the page's frames in headless chromium (web/movie.mjs) and encode them with ffmpeg (.mp4 or .gif)."""
    ext = os.path.splitext(out)[1].lower()
    if ext not in (".mp4", ".gif"):
        raise ViewError(f"{out}: --movie writes .mp4 or .gif")
    for tool, package in (("node", "nodejs"), ("ffmpeg", "ffmpeg")):
        if shutil.which(tool) is None:
            raise ViewError(f"--movie needs {tool} (Debian: apt-get install {package}; scripts/setup.sh installs it)")
    script = os.path.join(web_dir(), "movie.mjs")
    count = max(2, int(round(seconds * fps)))
    with tempfile.TemporaryDirectory(prefix="lgvi-movie-") as frames:
        subprocess.run(["node", script, os.path.abspath(html_path), frames, str(count), str(width), str(height)],
                       check=True)
        pattern = os.path.join(frames, "frame%05d.png")
        if ext == ".mp4":
            encode = ["-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "20"]
        else:
            encode = ["-filter_complex", "[0:v]split[a][b];[a]palettegen[p];[b][p]paletteuse"]
        subprocess.run(["ffmpeg", "-y", "-loglevel", "error", "-framerate", str(fps), "-i", pattern, *encode, out],
                       check=True)
    return out


def main(argv=None):
    """``python3 -m lgvi.viewer RUN_DIR``: exit 0, or 2 with one ``lgvi: error: ...`` line."""
    parser = argparse.ArgumentParser(prog="lgvi view", description="Write RUN_DIR/view.html, an interactive 3-D view.")
    parser.add_argument("run_dir")
    parser.add_argument("--out", help="the page's path (default RUN_DIR/view.html)")
    parser.add_argument("--max-frames", type=int, default=MAX_FRAMES)
    parser.add_argument("--open", action="store_true", help="open it in the default browser")
    parser.add_argument("--movie", help="also render a movie (.mp4 or .gif) in headless chromium with ffmpeg")
    parser.add_argument("--movie-seconds", type=float, default=10.0)
    parser.add_argument("-q", "--quiet", action="store_true")
    args = parser.parse_args(argv)
    try:
        if args.max_frames < 2:
            raise ViewError(f"--max-frames: must be >= 2, got {args.max_frames}")
        path, meta = _write_view(args.run_dir, args.out, args.max_frames, MAX_BYTES)
        if not args.quiet:
            note = decimation_note(meta, args.max_frames)
            if note:
                print(note, file=sys.stderr)
            print(f"lgvi view: wrote {path} ({os.path.getsize(path) / 1e6:.1f} MB)")
        if args.movie:
            make_movie(path, args.movie, args.movie_seconds)
            if not args.quiet:
                print(f"lgvi view: wrote {args.movie}")
        if args.open:
            print(open_in_browser(path))
    except (ViewError, ValueError) as e:
        print(f"lgvi: error: {e}", file=sys.stderr)
        return 2
    except subprocess.CalledProcessError as e:
        print(f"lgvi: error: {os.path.basename(e.cmd[0])} failed with status {e.returncode} (its message is above)",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
