"""lgvi view: the page generator (lgvi.viewer) and the page itself in a real browser.

The browser tests run `lgvi run` and `lgvi view` (the CLI), open view.html from
file:// in Debian's headless chromium (tests/view/view_check.mjs, puppeteer-core
from web/node_modules), read the displayed state back through window.lgviView
and compare it with the trajectory file, and check a screenshot: the body
colours at the projected positions of the bodies. Any console error, page
error or network request fails them.

Registered as ctest `view.pytest` (tests/CMakeLists.txt) with LGVI_BINARY,
LGVI_SOURCE_DIR and PYTHONPATH (the built package).
"""

import colorsys
import functools
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import lgvi
from lgvi import viewer

SOURCE = os.environ.get("LGVI_SOURCE_DIR", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
BINARY = os.environ.get("LGVI_BINARY", os.path.join(SOURCE, "build", "lgvi"))
CHECK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "view_check.mjs")
CHROMIUM = "/usr/bin/chromium"

# float32 rounds to nearest: relative error at most 2^-24 per embedded number.
F32 = 2.0 ** -24


def _browser_missing():
    missing = [what for what, ok in (
        ("node (apt-get install nodejs)", shutil.which("node")),
        (f"{CHROMIUM} (apt-get install chromium)", os.access(CHROMIUM, os.X_OK)),
        ("web/node_modules/puppeteer-core (npm ci --prefix web)",
         os.path.isdir(os.path.join(SOURCE, "web", "node_modules", "puppeteer-core"))),
        ("web/node_modules/three (npm ci --prefix web)",
         os.path.isdir(os.path.join(SOURCE, "web", "node_modules", "three")))) if not ok]
    return ", ".join(missing)


needs_browser = pytest.mark.skipif(bool(_browser_missing()),
                                   reason=f"missing {_browser_missing()}; scripts/setup.sh installs them")


def run_cli(*args, check=True):
    p = subprocess.run([BINARY, *args], capture_output=True, text=True)
    if check:
        assert p.returncode == 0, f"lgvi {' '.join(args)}: status {p.returncode}\n{p.stderr}"
    return p


def make_run(tmp_path_factory, scenario, name, replace=()):
    """Runs a bundled scenario (a name in scenarios/, or a path in the source tree) into a fresh folder;
    `replace`: (old, new) edits of its text, each of which must apply, the edited copy written beside the run."""
    folder = tmp_path_factory.mktemp(name)
    path = os.path.join(SOURCE, scenario if "/" in scenario else os.path.join("scenarios", scenario))
    if replace:
        with open(path, encoding="utf-8") as f:
            text = f.read()
        for old, new in replace:
            assert old in text
            text = text.replace(old, new)
        path = str(folder / os.path.basename(scenario))
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    out = str(folder / "run")
    run_cli("run", path, "--out", out, "--no-figures", "-q")
    return out


def drive(html, out_dir, plan):
    """Runs view_check.mjs; returns its report (problems, times, states, projection, overlay, ...)."""
    p = subprocess.run(["node", CHECK, html, str(out_dir), json.dumps(plan)], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, f"view_check.mjs failed ({p.returncode}):\n{p.stdout}\n{p.stderr}"
    with open(os.path.join(out_dir, "report.json"), encoding="utf-8") as f:
        report = json.load(f)
    assert report["problems"] == [], "the page reported problems (console errors or network requests)"
    return report


def screenshot(out_dir):
    import matplotlib.image
    return matplotlib.image.imread(os.path.join(out_dir, "screenshot.png"))[:, :, :3]  # floats in [0, 1]


def hue_sat(rgb):
    h, s, v = colorsys.rgb_to_hsv(*rgb)
    return h, s, v


def hue_distance(a, b):
    d = abs(a - b) % 1.0
    return min(d, 1.0 - d)


def is_colour_of(pixel, colour, tol=0.03):
    """The pixel shows this body colour: Lambert shading under white light scales the colour (its hue
    stays, to the 8-bit rounding: 0.03 of the hue circle) and the background and trails are grey."""
    h, s, v = hue_sat(pixel)
    return s > 0.3 and v > 0.15 and hue_distance(h, hue_sat(colour)[0]) < tol


def nlerp(qa, qb, u):
    qb = np.where((np.sum(qa * qb, axis=-1) < 0)[..., None], -qb, qb)
    q = qa + u * (qb - qa)
    return q / np.linalg.norm(q, axis=-1, keepdims=True), np.linalg.norm(q, axis=-1)


def check_states(report, t, x, q):
    """The displayed state at the requested times equals the trajectory file's rows (at embedded frames)
    or their interpolation (between frames), to the float32 rounding of the embedded data."""
    times = np.array(report["times"])
    for state in report["states"]:
        i, u = state["frame"], state["u"]
        pos, quat = np.array(state["positions"]), np.array(state["quaternions"])
        a = int(np.flatnonzero(t == times[i])[0])  # the embedded frame's row in the file
        if u == 0:
            # Exactly the row: |dx| <= 2^-24 |x|; q/|q| of the rounded q: <= 2^-24 per component plus
            # 2^-24 from the norm, plus the file's own |q| - 1 (< 1e-12): 2^-22 covers both.
            np.testing.assert_allclose(pos, x[a], rtol=F32, atol=1e-300)
            np.testing.assert_allclose(quat, q[a], rtol=0, atol=4 * F32)
        else:
            b = int(np.flatnonzero(t == times[i + 1])[0])
            assert abs(state["t"] - (times[i] + u * (times[i + 1] - times[i]))) < 1e-12 * max(1, abs(state["t"]))
            # Linear between the rounded rows: the rounding of each row, at most 2^-24 of the larger.
            bound = F32 * np.maximum(np.abs(x[a]), np.abs(x[b])) * 1.0000001 + 1e-300
            assert np.all(np.abs(pos - (x[a] + u * (x[b] - x[a]))) <= bound)
            # nlerp: the rounding (2^-24 per component, 2 for both rows and the norm) over |lerp|.
            expected, norm = nlerp(q[a], q[b], u)
            assert np.all(np.abs(quat - expected) <= 4 * F32 / norm[..., None])


# ------------------------------------------------------------------ without a browser

def test_inertia_ellipsoid_has_the_bodys_inertia():
    """Semi-axes from the principal moments: the solid ellipsoid (a, b, c) of mass m has
    J1 = m (b^2 + c^2) / 5 ..., here rotated; the quaternion turns the ellipsoid's axes into the body's."""
    m, axes = 2.5, np.array([0.3, 0.7, 1.1])
    q0 = np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2])
    R = lgvi.plot.rotation_matrix(q0)

    def moments(a):
        return m / 5 * np.array([a[1] ** 2 + a[2] ** 2, a[0] ** 2 + a[2] ** 2, a[0] ** 2 + a[1] ** 2])

    J = R @ np.diag(moments(axes)) @ R.T
    semi, q = viewer.inertia_ellipsoid(m, J)
    np.testing.assert_allclose(np.sort(semi), axes, rtol=1e-12)
    Rq = lgvi.plot.rotation_matrix(q)  # the drawn ellipsoid (semi-axes along Rq's columns) has inertia J
    np.testing.assert_allclose(Rq @ np.diag(moments(semi)) @ Rq.T, J, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(Rq), 1.0, atol=1e-12)


def test_point_bodies_are_drawn_with_a_size():
    """A point body (a single point mass, or a mass without inertia) has no size of its own: drawn as a ball
    of half the median size of the other parts (a triangle of point masses: dots a twentieth of its
    extent), or with nothing else of a hundredth of the scene's extent; never of size 0."""
    triangle = {"mass": 3.0, "balls": [{"position": p, "mass": 1.0} for p in ([1.0, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0])]}
    atom = {"mass": 1.0, "balls": [{"position": [0.0, 0.0, 0.0], "mass": 1.0}]}
    bare = {"mass": 1.0, "inertia": [[0.0] * 3] * 3}
    parts, _ = viewer._parts([triangle, atom, bare], {})
    viewer._size_points(parts, [0.0, 0.0, 0.0], [10.0, 0.0, 0.0])
    dot = 0.05 * 1.0  # the farthest point mass from the centre: 1.0
    np.testing.assert_allclose(parts[:3, 8:11], dot, rtol=1e-15)
    np.testing.assert_allclose(parts[3:, 8:11], 0.5 * dot, rtol=1e-15)  # the atom and the bare mass
    parts, _ = viewer._parts([atom, bare], {})
    viewer._size_points(parts, [0.0, 0.0, 0.0], [3.0, 4.0, 0.0])
    np.testing.assert_allclose(parts[:, 8:11], 0.05, rtol=1e-15)  # |extent| = 5


def test_decimation_is_even_and_keeps_the_last_row():
    idx = viewer._frames(1000001, 2000, 60, 36_000_000)
    assert len(idx) <= 2000 and idx[0] == 0 and idx[-1] == 1000000
    assert set(np.diff(idx[:-1])) == {501}  # ceil(1e6 / 1999)
    # The byte budget wins for many bodies: 10^4 bodies of 28 bytes a frame, 36 MB: 128 frames.
    assert len(viewer._frames(100001, 2000, 10000 * 28 + 32, 36_000_000)) <= 128
    np.testing.assert_array_equal(viewer._frames(11, 2000, 60, 36_000_000), np.arange(11))


def test_missing_threejs_names_the_fix(monkeypatch, tmp_path):
    monkeypatch.setattr(viewer, "_source_dirs", lambda: [str(tmp_path)])
    with pytest.raises(viewer.ViewError, match=r"three\.js is not installed.*scripts/setup\.sh.*npm ci --prefix web"):
        viewer.web_dir()


def test_view_of_a_folder_without_a_run_is_one_line_status_2(tmp_path):
    p = run_cli("view", str(tmp_path), check=False)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("lgvi: error: ")
    assert "no run here" in p.stderr and str(tmp_path) in p.stderr
    p = run_cli("view", str(tmp_path / "absent"), check=False)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "no such run folder" in p.stderr


def test_python_view_of_a_result_in_memory(tmp_path, tmp_path_factory):
    run = make_run(tmp_path_factory, "heavy-top.toml", "top")
    result = lgvi.load(run)
    with pytest.raises(ValueError, match="out="):
        lgvi.view(result)
    path = lgvi.view(result, out=str(tmp_path / "top.html"), max_frames=50)
    assert path == str(tmp_path / "top.html")
    html = open(path, encoding="utf-8").read()
    meta = json.loads(html.split('id="lgvi-meta">')[1].split("</script>")[0])
    # 2001 rows into at most 50 frames: every ceil(2000 / 49) = 41st row (0 .. 1968) and the last.
    assert meta["frames"] == 50 and meta["rows"] == 2001 and meta["decimated"]
    assert lgvi.view(run) == os.path.join(run, "view.html")
    # A pathlib.Path out (as a user writes it): the same file, its name returned as a str.
    assert lgvi.view(result, out=tmp_path / "top-path.html", max_frames=50, display=False) == str(tmp_path / "top-path.html")
    assert open(tmp_path / "top-path.html", encoding="utf-8").read() == html


def test_inline_display_in_jupyter(monkeypatch, tmp_path, tmp_path_factory):
    """A stand-in with IPython's names (get_ipython, IPython.display.display) checks lgvi.view's inline path
    without a kernel: in a Jupyter kernel (its shell is a ZMQInteractiveShell) it displays one raw MIME bundle,
    an iframe whose srcdoc is the page written (text/html) and the path (text/plain); in a terminal IPython it
    displays nothing; either way it returns the path. test_inline_display_in_a_real_jupyter_kernel runs the same
    call in a real kernel."""
    import html as html_module
    import sys
    import types

    shown, shell_class = [], {"name": "ZMQInteractiveShell"}
    ipython, display = types.ModuleType("IPython"), types.ModuleType("IPython.display")
    ipython.get_ipython = lambda: type(shell_class["name"], (), {})()
    display.display = lambda obj, raw=False: shown.append((obj, raw))
    monkeypatch.setitem(sys.modules, "IPython", ipython)
    monkeypatch.setitem(sys.modules, "IPython.display", display)
    run = make_run(tmp_path_factory, "heavy-top.toml", "inline")
    path = lgvi.view(run)
    assert path == os.path.join(run, "view.html") and len(shown) == 1
    bundle, raw = shown[0]
    assert raw and bundle["text/plain"] == f"lgvi view: {path}"
    frame = bundle["text/html"]
    assert frame.startswith('<iframe srcdoc="') and frame.endswith('" style="width:100%;height:640px;border:0"></iframe>')
    with open(path, encoding="utf-8") as f:
        assert html_module.unescape(frame[len('<iframe srcdoc="'):frame.index('" style=')]) == f.read()
    shell_class["name"] = "TerminalInteractiveShell"
    assert lgvi.view(run) == path and len(shown) == 1


def test_view_into_a_pipe_writes_into_it(tmp_path, tmp_path_factory):
    """--out naming a pipe or device (/dev/stdout) writes into it: it stays a pipe (the write-then-rename of a
    file would have put a file in its place; as root, even in place of /dev/null)."""
    import stat
    import threading

    run = make_run(tmp_path_factory, "heavy-top.toml", "pipe")
    fifo = str(tmp_path / "page.fifo")
    os.mkfifo(fifo)
    received = []
    reader = threading.Thread(target=lambda: received.append(open(fifo, "rb").read()), daemon=True)
    reader.start()
    assert viewer.write_view(run, out=fifo) == fifo
    reader.join(timeout=10)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and not os.path.exists(fifo + ".tmp")
    assert received and received[0].startswith(b"<!DOCTYPE html>") and received[0].rstrip().endswith(b"</html>")


def test_run_with_view_writes_the_page(tmp_path):
    out = str(tmp_path / "top")
    run_cli("run", os.path.join(SOURCE, "scenarios", "heavy-top.toml"), "--out", out, "--no-figures", "-q", "--view")
    html = open(os.path.join(out, "view.html"), encoding="utf-8").read()
    assert '"three":"data:text/javascript;base64,' in html.replace(" ", "")  # three.js inlined: no network
    assert "http://" not in html.split("<script type=\"importmap\">")[0] and "src=\"http" not in html


def test_open_without_a_display_says_where_the_page_is(tmp_path):
    out = str(tmp_path / "top")
    run_cli("run", os.path.join(SOURCE, "scenarios", "heavy-top.toml"), "--out", out, "--no-figures", "-q")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    p = subprocess.run([BINARY, "view", out, "--open"], capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    assert f"open file://{os.path.abspath(out)}/view.html in a browser" in p.stdout


# ------------------------------------------------------------------ in the browser

@pytest.fixture(scope="module")
def orbit(tmp_path_factory):
    run = make_run(tmp_path_factory, "paper-orbit.toml", "orbit")
    p = run_cli("view", run)
    assert "view.html" in p.stdout
    return run


@needs_browser
def test_paper_orbit_in_the_browser(orbit, tmp_path):
    html = os.path.join(orbit, "view.html")
    size = os.path.getsize(html)
    assert size < 50e6
    r = lgvi.load(orbit)
    t, x, q = r.t, r.x[:, None, :], r.q[:, None, :]
    # 10001 rows: every 6th embedded (ceil(10000 / 1999) = 6), 1668 frames; ask at frames and between.
    asked = [t[0], t[3000], t[3000] + 0.017, t[-1] - 0.03, t[-1]]
    report = drive(html, tmp_path, {"times": asked, "seek": t[3000],
                                     "set": {"follow": 0, "distance": 3.0, "trails": True}})
    assert report["rows"] == 10001 and report["frames"] == 1668
    assert report["drawn"] == {"meshInstances": 3, "quads": 0, "sprites": 0, "antialias": True}  # few parts: meshes
    assert "showing 1668 of 10001 frames" in report["overlay"]["note"]
    check_states(report, t, x, q)
    assert [s["u"] == 0 for s in report["states"]] == [True, True, False, False, True]
    # The overlay: the diagnostics of the row at t = 300, printed with 4 significant digits.
    row = 3000
    for name in ("energy_error", "quat_norm_error", "momentum_error"):
        shown = float(report["overlay"][name])
        assert abs(shown - r.columns[name][row]) <= 5e-4 * abs(r.columns[name][row])
    # The screenshot: each ball's colour at its projected centre (the three balls of radius 0.1 seen from 3:
    # about 25 px), background where no body is.
    img = screenshot(tmp_path)
    colour = report["colours"][0]
    balls = report["projection"]["parts"]
    assert len(balls) == 3
    for ball in balls:
        assert ball["radius"] > 10
        assert is_colour_of(img[round(ball["y"]), round(ball["x"])], colour), ball
    far = [(yy, xx) for yy in range(20, img.shape[0] - 20, 40) for xx in range(20, img.shape[1] - 20, 40)
           if all(np.hypot(xx - b["x"], yy - b["y"]) > 1.5 * b["radius"] for b in balls)]
    assert len(far) > 200
    assert not any(is_colour_of(img[yy, xx], colour, tol=0.1) for yy, xx in far)


def _jupyter_missing():
    try:
        import ipykernel  # noqa: F401
        import jupyter_client  # noqa: F401
    except ImportError as e:
        return f"{e.name} (apt-get install python3-ipykernel python3-jupyter-client; scripts/setup.sh installs them)"
    return ""


@needs_browser
@pytest.mark.skipif(bool(_jupyter_missing()), reason=f"missing {_jupyter_missing()}")
def test_inline_display_in_a_real_jupyter_kernel(orbit, tmp_path):
    """lgvi.view in a real Jupyter kernel (Debian's ipykernel, driven through jupyter_client as a notebook
    frontend does): the kernel publishes one display_data whose text/html is an iframe holding the page written,
    and the call's value is the path. That output, placed in a page as a notebook places it, runs the view
    inside the iframe in chromium: the displayed states equal the trajectory's rows, the balls are drawn at
    their projected positions, with no console error and no network request."""
    import html as html_module
    import sys

    import jupyter_client

    out = str(tmp_path / "inline.html")
    # The kernel is this interpreter (the one that imports lgvi), as a kernelspec of its own.
    spec = tmp_path / "kernels" / "lgvi-test"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-Xfrozen_modules=off", "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "lgvi test", "language": "python"}))
    env = dict(os.environ, JUPYTER_PATH=str(tmp_path), PYTHONPATH=os.pathsep.join(sys.path))
    km = jupyter_client.KernelManager(kernel_name="lgvi-test")
    km.kernel_spec_manager.kernel_dirs = [str(tmp_path / "kernels")]
    km.start_kernel(env=env)
    try:
        kc = km.client()
        kc.start_channels()
        kc.wait_for_ready(timeout=120)
        outputs = []
        reply = kc.execute_interactive(f"import lgvi\nlgvi.view({orbit!r}, out={out!r})", timeout=300,
                                       output_hook=outputs.append)
        kc.stop_channels()
    finally:
        km.shutdown_kernel(now=True)
    assert reply["content"]["status"] == "ok", reply["content"]
    kinds = [m["header"]["msg_type"] for m in outputs if m["header"]["msg_type"] != "status"]
    # Nothing else: no stream (a warning on stderr would be one; IPython's HTML object gave one for an iframe).
    assert kinds == ["execute_input", "display_data", "execute_result"], outputs
    shown = next(m for m in outputs if m["header"]["msg_type"] == "display_data")["content"]["data"]
    value = next(m for m in outputs if m["header"]["msg_type"] == "execute_result")["content"]["data"]
    assert value["text/plain"] == repr(out) and shown["text/plain"] == f"lgvi view: {out}"
    frame = shown["text/html"]
    assert frame.startswith('<iframe srcdoc="') and frame.endswith('" style="width:100%;height:640px;border:0"></iframe>')
    with open(out, encoding="utf-8") as f:
        assert html_module.unescape(frame[len('<iframe srcdoc="'):frame.index('" style=')]) == f.read()

    # The output in a page, as a notebook shows it (an output area of the page's width, no margin).
    notebook = tmp_path / "notebook.html"
    notebook.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"></head><body style="margin:0">'
                        f'<div class="output_html">{frame}</div></body></html>', encoding="utf-8")
    r = lgvi.load(orbit)
    t, x, q = r.t, r.x[:, None, :], r.q[:, None, :]
    asked = [t[0], t[3000], t[3000] + 0.017, t[-1]]
    report = drive(str(notebook), tmp_path, {"times": asked, "seek": t[3000], "inFrame": True, "height": 640,
                                             "set": {"follow": 0, "distance": 3.0, "trails": True}})
    assert report["rows"] == 10001 and report["frames"] == 1668
    check_states(report, t, x, q)
    # The iframe fills the page's top 960 x 640 pixels, so the view's projected positions are page pixels.
    img = screenshot(tmp_path)
    balls = report["projection"]["parts"]
    assert len(balls) == 3
    for ball in balls:
        assert ball["radius"] > 10
        assert is_colour_of(img[round(ball["y"]), round(ball["x"])], report["colours"][0]), ball


@needs_browser
def test_many_bodies_in_the_browser(tmp_path_factory, tmp_path):
    run = make_run(tmp_path_factory, "lj-gas.toml", "gas")
    run_cli("view", run, "-q")
    html = os.path.join(run, "view.html")
    r = lgvi.load(run)
    report = drive(html, tmp_path, {"times": [r.t[0], r.t[5], r.t[5] + 0.05, r.t[-1]], "seek": r.t[5],
                                     "set": {"trails": False}})
    assert report["rows"] == report["frames"] == 11  # 1000 steps, every 100th written: all embedded
    # 3000 balls: more than 2000 parts, drawn as sprites (shaded spheres, one vertex each), not mesh instances.
    assert report["drawn"] == {"meshInstances": 0, "quads": 0, "sprites": 3000, "antialias": False}
    assert "all 11 frames" in report["overlay"]["note"]
    check_states(report, r.t, r.x, r.q)
    # The screenshot: at each molecule's projected centre of mass the colour is that of the ball nearest the
    # camera there (molecules hide each other in the gas; a molecule's own centre lies between its balls, 0.577
    # from each, radius 0.5). The hues are golden-ratio steps, so a wrong position or attitude shows another
    # hue. Pixels within 10 % of the front ball's projected edge are ambiguous (edges are antialiased, and an
    # off-axis sphere projects to an ellipse slightly larger than the disk assumed here): skipped. Measured:
    # 572 of 574 unambiguous centres match (99.7 %; 562 when the sprites were shaded for a ray along the view
    # axis), 426 skipped.
    img = screenshot(tmp_path)
    proj = report["projection"]
    parts = proj["parts"]
    px, py = np.array([p["x"] for p in parts]), np.array([p["y"] for p in parts])
    depth, rad = np.array([p["depth"] for p in parts]), np.array([p["radius"] for p in parts])
    size = np.array([p["size"] for p in parts])
    owner = np.array([p["body"] for p in parts], dtype=int)
    matched = checked = 0
    for body in proj["bodies"]:
        d = np.hypot(px - body["x"], py - body["y"])
        near = np.flatnonzero(d < 1.1 * rad + 1)
        if near.size == 0:
            continue
        # Depth of each sphere's surface along the ray through the pixel (its centre's depth off the sphere).
        surface = depth[near] - np.sqrt(np.maximum(size[near] ** 2 - (d[near] * size[near] / rad[near]) ** 2, 0.0))
        front = near[np.argmin(surface)]
        if d[front] > 0.9 * rad[front]:
            continue
        checked += 1
        matched += is_colour_of(img[round(body["y"]), round(body["x"])], report["colours"][owner[front]])
    assert checked >= 400
    assert matched >= 0.95 * checked, f"{matched} of {checked} centres show the expected molecule's colour"


@needs_browser
def test_a_periodic_box_in_the_browser(tmp_path_factory, tmp_path):
    """The periodic gas (lj-gas.toml in the cube [-1.1, 20.9)^3, 1000 steps): the page draws the box and shows
    each centre of mass wrapped into it, x -> lower + (x - lower) mod 22, from the file's unwrapped positions (to
    the float32 rounding of the embedded data: 2^-24 of |x| before wrapping, plus that of the subtraction), and
    wraps after interpolating, so a body between frames is where its unwrapped path puts it."""
    lo, hi = -1.1, 20.9
    run = make_run(tmp_path_factory, "lj-gas.toml", "periodic-gas", replace=[(
        "[output]", f"[box]\nlower = [{lo}, {lo}, {lo}]\nupper = [{hi}, {hi}, {hi}]\n\n[output]")])
    run_cli("view", run, "-q")
    r = lgvi.load(run)
    meta, _ = viewer.page_data(r)
    assert meta["periodic_box"] == {"lower": [lo] * 3, "upper": [hi] * 3, "periodic": [True] * 3}
    report = drive(os.path.join(run, "view.html"), tmp_path, {"times": [r.t[0], r.t[-1], r.t[5] + 0.05],
                                                            "seek": r.t[-1], "set": {"trails": True}})
    # Angular momentum is not conserved in a periodic box: the overlay calls its column a change.
    assert report["overlay"]["momentum_error"] != "" and report["overlay"]["time"] != "NaN"
    assert report["box"]["lower"] == pytest.approx([lo] * 3) and report["box"]["upper"] == pytest.approx([hi] * 3)
    states = report["states"]
    length = hi - lo
    # Some bodies have left the box by the end (unwrapped), so that the wrapping is exercised.
    outside = np.any((r.x[-1] < lo) | (r.x[-1] >= hi), axis=1)
    assert outside.sum() >= 5
    for state, x in ((states[0], r.x[0]), (states[1], r.x[-1])):
        pos = np.array(state["positions"])
        assert np.all((pos >= lo) & (pos < hi))
        expected = lo + np.mod(x - lo, length)
        # Where the float32 value lands within its rounding of a face, it may wrap to the other face.
        d = np.abs(pos - expected)
        d = np.minimum(d, np.abs(d - length))
        assert np.all(d <= 4 * F32 * (np.abs(x) + length)), d.max()
    # Between frames: the unwrapped interpolation, wrapped.
    i, u = states[2]["frame"], states[2]["u"]
    a, b = (int(np.flatnonzero(r.t == report["times"][k])[0]) for k in (i, i + 1))
    expected = lo + np.mod(r.x[a] + u * (r.x[b] - r.x[a]) - lo, length)
    d = np.abs(np.array(states[2]["positions"]) - expected)
    assert np.all(np.minimum(d, np.abs(d - length)) <= 4 * F32 * (np.abs(r.x[b]) + length))


def ray_cast(camera, width, height, xs, ys, centres, rotations, axes, clip=0.0):
    """The reference picture: per pixel (xs, ys: screen pixels from the top left, the ray through the pixel's
    centre), the index of the ellipsoid (centres, rotations: its axes as columns, semi-axes) nearest the camera
    along it, -1 where none is hit; in float64, from the page's camera (project()'s column-major matrices). An
    ellipsoid whose front surface along the ray is nearer than `clip` (a view depth: the ray's parameter t, d
    having view z = -1) is not hit there (clipped, as a mesh with its back faces culled is)."""
    view, proj = (np.array(camera[k], dtype=float).reshape(4, 4).T for k in ("view", "projection"))
    ndc_x, ndc_y = 2 * (np.asarray(xs) + 0.5) / width - 1, 1 - 2 * (np.asarray(ys) + 0.5) / height
    d = np.stack([(ndc_x + proj[0, 2]) / proj[0, 0], (ndc_y + proj[1, 2]) / proj[1, 1], -np.ones_like(ndc_x)], -1)
    world = np.linalg.inv(view)
    origin, dirs = world[:3, 3], d @ world[:3, :3].T
    unit = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    front, nearest = np.full(len(dirs), -1), np.full(len(dirs), np.inf)
    for k, (c, rot, a) in enumerate(zip(centres, rotations, axes)):
        w = c - origin
        along = unit @ w
        near = np.flatnonzero(w @ w - along ** 2 <= a.max() ** 2)  # rays through the bounding sphere
        if near.size == 0:
            continue
        n = rot / a  # the ellipsoid: |n^T (p - c)| = 1
        e, m = dirs[near] @ n, w @ n
        ee = np.sum(e * e, axis=1)
        t0 = e @ m / ee
        h2 = np.sum((t0[:, None] * e - m) ** 2, axis=1)
        t = t0 - np.sqrt(np.maximum(1 - h2, 0) / ee)
        closer = (h2 <= 1) & (t > clip) & (t < nearest[near])
        front[near[closer]], nearest[near[closer]] = k, t[closer]
    return front


@needs_browser
def test_many_ellipsoids_in_the_browser(tmp_path_factory, tmp_path):
    """The lattice of benchmarks/view/ellipsoids-10k.toml cut to 13^3 = 2197 bodies given by mass and inertia:
    more than 2000 parts, so every inertia ellipsoid (semi-axes 1.80, 1.32, 0.50) is a sprite ray-cast per pixel.
    The camera follows one of the bodies nearest it from 10 away; the screenshot against a reference ray cast of
    the ellipsoids from the trajectory file (positions, attitudes) and lgvi's inertia ellipsoid."""
    run = make_run(tmp_path_factory, "benchmarks/view/ellipsoids-10k.toml", "ellipsoids",
                   replace=(("count = 10000", "count = 2197"), ("duration = 1.0", "duration = 0.1")))
    run_cli("view", run, "-q")
    r = lgvi.load(run)
    width, height = 960, 640
    x, q = r.x[1], r.q[1]  # the seek time below: an embedded row, drawn exactly
    axes, q_part = viewer.inertia_ellipsoid(1.0, np.diag([0.4, 0.7, 1.0]))
    np.testing.assert_allclose(axes, [np.sqrt(3.25), np.sqrt(1.75), 0.5], rtol=1e-12)  # a^2 = 5 (J2 + J3 - J1) / 2
    rotations = lgvi.plot.rotation_matrix(q) @ lgvi.plot.rotation_matrix(q_part)
    # The camera looks along -v; of the 3 bodies nearest it, the one whose outline (seen along v) is the most
    # elongated: the principal widths of the ellipsoid projected along v, from R diag(a^2) R^T projected.
    v = np.array([0.55, -1.0, 0.65]) / np.linalg.norm([0.55, -1.0, 0.65])
    flat = np.eye(3) - np.outer(v, v)
    widths = np.linalg.eigvalsh(flat @ rotations @ np.diag(axes ** 2) @ np.swapaxes(rotations, 1, 2) @ flat)
    nearest = np.argsort(-(x @ v))[:3]
    followed = int(nearest[np.argmax(widths[nearest, 2] / widths[nearest, 1])])
    report = drive(os.path.join(run, "view.html"), tmp_path,
                   {"times": [r.t[1]], "seek": r.t[1], "width": width, "height": height,
                    "set": {"trails": False, "follow": followed, "distance": 10.0}})
    assert report["drawn"] == {"meshInstances": 0, "quads": 2197, "sprites": 0, "antialias": False}
    check_states(report, r.t, r.x, r.q)
    cast = functools.partial(ray_cast, report["projection"]["camera"], width, height,
                             centres=x, rotations=rotations, axes=np.tile(axes, (len(x), 1)))
    img = screenshot(tmp_path)
    colours = report["colours"]

    def shows(pixel, body):  # body -1: none, the background or the grid (grey or dark, is_colour_of's limits)
        if body >= 0:
            return is_colour_of(pixel, colours[body])
        _, s, v = hue_sat(pixel)
        return s <= 0.3 or v <= 0.15

    # Every 4th pixel each way: the body in front there (or none) is the reference's. Unambiguous pixels only:
    # those whose ray and the rays half a pixel off each way meet the same body (or none): a pixel's colour
    # at an outline, or where two bodies' surfaces cross, depends on the rounding of the float32 ray.
    ys, xs = (g.ravel() for g in np.mgrid[2:height:4, 2:width:4])
    shifts = [(0, 0), (0.5, 0), (-0.5, 0), (0, 0.5), (0, -0.5)]
    fronts = np.array([cast(xs=xs + dx, ys=ys + dy) for dx, dy in shifts])
    sure = np.all(fronts == fronts[0], axis=0)
    assert np.sum(sure & (fronts[0] >= 0)) > 20000 and np.sum(sure & (fronts[0] < 0)) > 2000
    wrong = [(y, x_, b) for y, x_, b in zip(ys[sure], xs[sure], fronts[0][sure]) if not shows(img[y, x_], b)]
    assert len(wrong) <= 0.001 * np.sum(sure), f"{len(wrong)} of {np.sum(sure)} pixels: {wrong[:10]}"  # measured 0
    # The followed body's outline at full resolution, about its projected centre (the screen's centre): the
    # pixels of its colour are those the reference gives it, but for the rounding at the outline (either set
    # within a pixel of the other), where no look-alike body shows (the reference's front body of a hue within
    # twice is_colour_of's tolerance: the yellow one behind it here). Measured: the same 15010 pixels.
    centre = report["projection"]["bodies"][followed]
    reach = 1.2 * report["projection"]["parts"][followed]["radius"] + 2  # beyond the bounding sphere's outline
    rows, cols = np.mgrid[int(centre["y"] - reach):int(centre["y"] + reach) + 1,
                          int(centre["x"] - reach):int(centre["x"] + reach) + 1]
    front = cast(xs=cols.ravel(), ys=rows.ravel()).reshape(rows.shape)
    hue = hue_sat(colours[followed])[0]
    alike = np.vectorize(lambda b: b != followed and b >= 0 and hue_distance(hue_sat(colours[b])[0], hue) < 0.06)(front)
    mine = front == followed
    seen = np.vectorize(lambda y, x_: is_colour_of(img[y, x_], colours[followed]))(rows, cols) & ~alike

    def grown(mask):  # the mask and its 8 neighbours
        g = np.pad(mask, 1)
        return np.any([g[1 + dy:g.shape[0] - 1 + dy, 1 + dx:g.shape[1] - 1 + dx]
                       for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)

    assert mine.sum() > 10000  # measured 15010: unhidden (the reference without the other bodies gives as many)
    assert not np.any(seen & ~grown(mine)) and not np.any(mine & ~grown(seen))

    def shape(mask):  # the silhouette's principal half widths (2 sqrt of the second moments: exact for an
        # ellipse), and the direction of the longer, degrees mod 180
        v, w = np.linalg.eigh(np.cov(np.array([cols[mask], rows[mask]], dtype=float)))
        return 2 * np.sqrt(v[1]), 2 * np.sqrt(v[0]), np.degrees(np.arctan2(w[1, 1], w[0, 1])) % 180

    # Elongated as the reference: reaching along its long axis beyond the short half width, but not beyond the
    # long one. An outline moved by a pixel changes a half width (here about 110 and 43 px) by a pixel: 3 % of
    # the short one, and the direction by 1 px over 110 (0.5 degree).
    (long, short, angle), (long_seen, short_seen, angle_seen) = shape(mine), shape(seen)
    assert long > 2 * short  # measured: 2.57 (the ellipsoid's outline seen along v: 2.58)
    assert abs(long_seen - long) < 1 and abs(short_seen - short) < 1
    assert abs((angle_seen - angle + 90) % 180 - 90) < 0.5


@needs_browser
def test_ellipsoids_at_the_near_plane_in_the_browser(tmp_path_factory, tmp_path):
    """Quads where the outline is no ellipse: the camera follows the body nearest it (benchmarks/view's lattice cut to
    2197 inertia ellipsoids, as above) from so close that the body touches the plane through the eye (the near plane
    cuts a cap off it: the quad falls back to the screen box of the part beyond the near plane), and then from
    inside it (the ellipsoid crosses the eye's plane; the page must show nothing of it, not smear it over the
    screen). The screenshot against the reference ray cast with the near plane's clipping: a body's front surface
    nearer than the near plane is not drawn there, the bodies behind are. (With the near plane at 10^-3 of the
    scene's radius, a cut edge shows on the screen only at grazing incidence, where following a body along the
    page's view direction does not put the camera.)"""
    run = make_run(tmp_path_factory, "benchmarks/view/ellipsoids-10k.toml", "near",
                   replace=(("count = 10000", "count = 2197"), ("duration = 1.0", "duration = 0.1")))
    run_cli("view", run, "-q")
    r = lgvi.load(run)
    width, height = 960, 640
    x, q = r.x[1], r.q[1]
    axes, q_part = viewer.inertia_ellipsoid(1.0, np.diag([0.4, 0.7, 1.0]))
    rotations = lgvi.plot.rotation_matrix(q) @ lgvi.plot.rotation_matrix(q_part)
    v = np.array([0.55, -1.0, 0.65]) / np.linalg.norm([0.55, -1.0, 0.65])  # from the target to the camera
    followed = int(np.argmax(x @ v))
    rot = rotations[followed]
    support = np.sqrt(v @ rot @ np.diag(axes ** 2) @ rot.T @ v)  # the body's half depth along the view
    inside = 0.5 / np.linalg.norm((rot / axes).T @ v)  # half way from its centre to its surface, towards the camera
    ys, xs = (g.ravel() for g in np.mgrid[2:height:4, 2:width:4])
    shifts = [(0, 0), (0.5, 0), (-0.5, 0), (0, 0.5), (0, -0.5)]
    for case, distance in (("touching the eye's plane", support), ("camera inside", inside)):
        out = tmp_path / case.replace(" ", "-").replace("'", "")
        out.mkdir()
        report = drive(os.path.join(run, "view.html"), out,
                       {"times": [r.t[1]], "seek": r.t[1], "width": width, "height": height,
                        "set": {"trails": False, "follow": followed, "distance": float(distance)}})
        assert report["drawn"] == {"meshInstances": 0, "quads": 2197, "sprites": 0, "antialias": False}
        colours = report["colours"]
        camera = report["projection"]["camera"]
        m = np.array(camera["projection"])  # column-major: m[10] = -(f + n) / (f - n), m[14] = -2 f n / (f - n)
        near = m[14] / (m[10] - 1)
        cast = functools.partial(ray_cast, camera, width, height, centres=x, rotations=rotations,
                                 axes=np.tile(axes, (len(x), 1)), clip=near)
        img = screenshot(out)
        fronts = np.array([cast(xs=xs + dx, ys=ys + dy) for dx, dy in shifts])
        sure = np.all(fronts == fronts[0], axis=0)

        def shows(pixel, body):  # as in test_many_ellipsoids_in_the_browser
            if body >= 0:
                return is_colour_of(pixel, colours[body])
            _, s_, v_ = hue_sat(pixel)
            return s_ <= 0.3 or v_ <= 0.15

        wrong = [(y, x_, b) for y, x_, b in zip(ys[sure], xs[sure], fronts[0][sure]) if not shows(img[y, x_], b)]
        assert np.sum(sure) > 30000
        # Measured: 0 wrong of 38391 sure pixels (touching), 0 of 37970 (inside).
        assert len(wrong) <= 0.001 * np.sum(sure), f"{case}: {len(wrong)} of {np.sum(sure)} pixels: {wrong[:10]}"
        mine = np.sum(sure & (fronts[0] == followed))
        if case == "camera inside":
            assert mine == 0  # nothing of the body around the camera; the others are drawn (the check above)
        else:
            # The body fills the screen but for a corner (measured: 37986 of 38391 sure pixels; the cap that the near
            # plane cuts off lies off the screen, about the point where the body touches the eye's plane).
            assert mine > 30000 and np.sum(sure & (fronts[0] != followed)) > 100


@needs_browser
def test_movie(orbit, tmp_path):
    out = str(tmp_path / "orbit.mp4")
    p = run_cli("view", orbit, "--movie", out, "--movie-seconds", "0.4", check=False)
    assert p.returncode == 0, p.stderr
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                            "stream=nb_read_frames,width,height", "-of", "json", out],
                           capture_output=True, text=True, check=True)
    stream = json.loads(probe.stdout)["streams"][0]
    assert int(stream["nb_read_frames"]) == 12  # 0.4 s at 30 frames/s
    assert (stream["width"], stream["height"]) == (1280, 720)


@needs_browser
def test_the_pole_of_a_j2_field_in_the_browser(tmp_path_factory, tmp_path):
    """The LEO scenario about an Earth whose pole is tilted to (0, 0.6, 0.8), for 10 orbits (100 rows): the page
    draws the source as the sphere of the reference radius and the pole's axis through it, along the scenario's
    pole, in the pole's colour where it projects, and nowhere else."""
    run = make_run(tmp_path_factory, "leo-gravity-gradient.toml", "oblate",
                   replace=(("pole = [0.0, 0.0, 1.0]", "pole = [0.0, 0.6, 0.8]"),
                            ("duration = 5676978.0", "duration = 56769.78")))
    run_cli("view", run, "-q")
    report = drive(os.path.join(run, "view.html"), tmp_path, {"times": [], "seek": 0.0, "set": {"trails": True}})
    pole = report["pole"]
    # The drawn axis, read back from the scene graph: the scenario's unit pole after a few double-precision
    # operations (the summary's 17 digits, a normalization, a rotation from y): round-off of order 1e-16.
    np.testing.assert_allclose(pole["direction"], [0.0, 0.6, 0.8], rtol=0, atol=1e-12)
    # The source is the Earth (reference radius 6378137 m; the orbit at 6878137 m stays outside it).
    assert pole["sourceRadius"] == 6378137.0 and pole["half"] == 1.5 * 6378137.0
    img = screenshot(tmp_path)
    height, width = img.shape[:2]
    colour = np.array(pole["colour"])
    source = report["projection"]["source"]

    def shows_pole(yy, xx):
        # Unlit: the pole's sRGB colour to the 8-bit rounding (0.5/255), 3/255 for the linear-to-sRGB round trip.
        return np.max(np.abs(img[yy, xx] - colour)) < 3 / 255

    # Points of the axis outside the Earth's disc (and 3 px off its antialiased edge) and on the screen: the pole's
    # colour within a pixel of each (the shaft is about 6 px wide here; where the south end pierces the plane of
    # the grid, a 1-px grid line in front of it can cross the very pixel).
    visible = [p for p in report["projection"]["pole"]
               if np.hypot(p["x"] - source["x"], p["y"] - source["y"]) > source["radius"] + 3
               and 3 <= p["x"] < width - 3 and 3 <= p["y"] < height - 3 and abs(p["s"]) < 0.95]
    assert len(visible) >= 4, report["projection"]["pole"]  # measured: 2 south of the disc, 2 north of it
    for p in visible:
        x, y = round(p["x"]), round(p["y"])
        assert any(shows_pole(y + dy, x + dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)), p
    # Nowhere far (20 px) from the axis's projected segment is there a pixel of the pole's colour.
    ends = [np.array([p["x"], p["y"]]) for p in (report["projection"]["pole"][0], report["projection"]["pole"][-1])]

    def distance_to_axis(xx, yy):
        a, b, v = ends[0], ends[1], np.array([xx, yy])
        u = np.clip(np.dot(v - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        return np.linalg.norm(v - (a + u * (b - a)))

    far = [(yy, xx) for yy in range(5, height - 5, 7) for xx in range(5, width - 5, 7) if distance_to_axis(xx, yy) > 20]
    assert len(far) > 5000
    assert not any(shows_pole(yy, xx) for yy, xx in far)


@needs_browser
def test_a_million_rows_in_the_browser(tmp_path_factory, tmp_path):
    """Hairer's free body with a step of 0.0005 for t = 500, every step written (npz): 10^6 + 1 rows. lgvi view
    decimates them to the page's budget and says so; the page loads without problems and shows the kept rows
    (and interpolates between them). Measured on 2 shared cores: run 1.4 s, view 5 s, browser 10 s."""
    run = make_run(tmp_path_factory, "free-body-hairer.toml", "long",
                   replace=(("step = 0.05", "step = 0.0005"), ("every = 10", 'every = 1\nformat = "npz"')))
    p = run_cli("view", run)
    # 10^6 intervals into at most 2000 frames: every ceil(10^6 / 1999) = 501st row (0 .. 999999, 1996 of them)
    # and the last.
    assert p.stderr == ("lgvi view: 1000001 rows decimated to 1998 frames (every k-th row and the last; the page "
                        "embeds at most 2000 frames and 36 MB of frame data, --max-frames) and interpolates between "
                        "them\n")
    html = os.path.join(run, "view.html")
    assert os.path.getsize(html) < 5e6  # 1998 frames of one body: 3.2 MB, most of it three.js
    r = lgvi.load(run)
    assert len(r.t) == 1000001
    # Kept rows (0, 501 k, the last) and times between them, where the nearest kept rows are interpolated.
    asked = [r.t[0], r.t[501 * 777], r.t[501 * 777] + 0.1, r.t[501 * 1996], r.t[-1] - 0.001, r.t[-1]]
    report = drive(html, tmp_path, {"times": asked, "seek": asked[2]})
    assert report["rows"] == 1000001 and report["frames"] == 1998
    assert "showing 1998 of 1000001 frames" in report["overlay"]["note"]
    check_states(report, r.t, r.x[:, None, :], r.q[:, None, :])
    assert [s["frame"] for s in report["states"]] == [0, 777, 777, 1996, 1996, 1997]
    assert [s["u"] == 0 for s in report["states"]] == [True, True, False, True, False, True]
