"""Showing a ``PlanView`` (``sim.view``): a self-contained HTML page (meshcat's bundled three.js viewer
and every command inlined, so it opens from a file with no server and no network), or meshcat's live
server on this machine."""

from __future__ import annotations

import base64
import html
import os
import shutil
import signal
import subprocess
import tempfile
import time
import webbrowser
from typing import Callable, Optional

import meshcat
import umsgpack

from pickplan.core.io import write_text
from pickplan.sim.view import PlanView, legend_entries
from pickplan.sim.view_server import LOOPBACK, start_server

VIEWER_SCRIPT = os.path.join(meshcat.viewer_assets_path(), "dist", "main.min.js")

# Commands are decoded and applied in order, synchronously: set_animation finds its targets by path,
# so it must come after the objects (meshcat's own static page fetches each one asynchronously).
_PAGE = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#legend {{ position: absolute; left: 8px; bottom: 8px; padding: 6px 10px; font: 13px sans-serif;
          background: rgba(255, 255, 255, 0.85); border-radius: 4px; }}
#legend span.swatch {{ display: inline-block; width: 12px; height: 12px; margin-right: 6px; vertical-align: middle; }}
</style></head>
<body>
<div id="meshcat-pane"></div>
<div id="legend"><b>{title}</b><br>{legend}<br>time slider: Animations &gt; default &gt; time ({duration:.1f} s); page#t=SECONDS opens at a moment</div>
<script>
{viewer}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var pickplanCommands = [
{commands}
];
for (const encoded of pickplanCommands) {{
  const bytes = Uint8Array.from(atob(encoded), (c) => c.charCodeAt(0));
  viewer.handle_command_bytearray(bytes);
}}
viewer.gui.open();  // the time slider in view from the start
// Played and paused at once: the actions are live, so the time slider moves the robot, but nothing
// redraws until asked. A link ending in #t=SECONDS opens the plan at that moment.
viewer.animator.play();
viewer.animator.pause();
const moment = /[#&]t=([0-9.]+)/.exec(location.hash);
if (moment) {{
  viewer.animator.seek(parseFloat(moment[1]));
  viewer.animator.display_progress(parseFloat(moment[1]));
}}
</script>
</body>
</html>
"""


def _packed(command) -> bytes:
    return umsgpack.packb(command.lower())


def page_html(view: PlanView) -> str:
    """The self-contained page: no external script, style or data."""
    with open(VIEWER_SCRIPT, "r", encoding="utf-8") as f:
        viewer = f.read()
    if "</script" in viewer.lower():  # would end the inline script early
        raise RuntimeError(f"{VIEWER_SCRIPT} contains '</script': cannot inline it")
    commands = ",\n".join(f'"{base64.b64encode(_packed(c)).decode("ascii")}"' for c in view.commands)
    legend = "<br>".join(
        f'<span class="swatch" style="background:{color}"></span>{html.escape(label)}'
        for label, color in legend_entries()
    )
    return _PAGE.format(
        title=html.escape(view.title), legend=legend, duration=view.duration, viewer=viewer, commands=commands
    )


def write_html(view: PlanView, path: str) -> str:
    """Write the page to ``path`` (atomically); returns the absolute path."""
    write_text(path, page_html(view))
    return os.path.abspath(path)


def serve(
    view: PlanView,
    open_browser: bool = False,
    keep_running: Optional[Callable[[], bool]] = None,
    announce: Callable[[str], None] = print,
    host: str = LOOPBACK,
) -> str:
    """Start meshcat's server (a subprocess; its web server on ``host`` only, loopback by default:
    ``sim.view_server``), send the view to it and announce its URL. Runs until ``keep_running()``
    is false (default: until Ctrl-C); returns the URL."""
    proc, zmq_url, url = start_server(host)
    try:
        vis = meshcat.Visualizer(zmq_url=zmq_url)
        for command in view.commands:
            vis.window.send(command)
        announce(f"viewer at {url} (Ctrl-C to stop)")
        if open_browser:
            webbrowser.open(url, new=2)
        while keep_running is None or keep_running():
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        proc.kill()
        proc.wait()
    return url


def find_chromium() -> Optional[str]:
    """The headless browser the screenshots use (Debian's ``chromium``), or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(
    page: str,
    png: str,
    width: int = 1200,
    height: int = 800,
    wait_ms: int = 5000,
    attempts: int = 3,
    moment: Optional[float] = None,
    timeout: float = 120.0,
) -> str:
    """Render the page ``page`` in headless Chromium (software WebGL, all network off) to ``png``,
    with the robot at ``moment`` seconds into the motion (default: the start). ``wait_ms`` of virtual
    time lets the canvas draw. Returns ``png``'s path."""
    browser = find_chromium()
    if browser is None:
        raise FileNotFoundError("chromium not found (Debian package `chromium`): cannot take a screenshot")
    page, png = os.path.abspath(page), os.path.abspath(png)
    if not os.path.isfile(page):
        raise FileNotFoundError(f"page not found: {page}")
    url = f"file://{page}" + (f"#t={moment}" if moment is not None else "")
    # On a loaded machine the software renderer now and then stalls: such a start is stopped (its
    # whole process group) and tried again.
    for _ in range(attempts):
        with tempfile.TemporaryDirectory(prefix="pickplan-chromium-") as profile:
            if os.path.exists(png):
                os.unlink(png)
            proc = subprocess.Popen(
                [
                    browser,
                    "--headless",
                    "--no-sandbox",
                    "--disable-gpu",
                    "--use-gl=swiftshader",
                    "--enable-unsafe-swiftshader",
                    f"--user-data-dir={profile}",
                    "--host-resolver-rules=MAP * ~NOTFOUND",
                    "--no-first-run",
                    f"--window-size={width},{height}",
                    f"--virtual-time-budget={wait_ms}",
                    f"--screenshot={png}",
                    url,
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                continue
        if os.path.isfile(png) and os.path.getsize(png) > 0:
            return png
    raise RuntimeError(f"chromium wrote no screenshot of {url} in {attempts} attempts")
