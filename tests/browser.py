"""Opening a Meshcat HTML file in headless Chromium and listing the scene it builds.

`./run test` installs Chromium from the Debian packages when it is missing. The page's own
script runs (WebGL through SwiftShader); a small script added at the end of a copy of the page
writes what a test asks for (the names of Meshcat's scene tree, or an image its viewer
renders) into the DOM, which `--dump-dom` prints.
"""

from __future__ import annotations

import base64
import html
import json
import re
import shutil
import subprocess
from pathlib import Path

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")

_PROBE = """<script>
function physcapSceneNames(node, depth) {
  const names = {};
  if (depth > 5) return names;
  for (const [name, child] of Object.entries(node.children || {}))
    names[name] = physcapSceneNames(child, depth + 1);
  return names;
}
setTimeout(function () {
  const out = document.createElement("pre");
  out.id = "physcap-probe";
  try { out.textContent = JSON.stringify(%s); }
  catch (error) { out.textContent = "ERROR " + error; }
  document.body.appendChild(out);
}, 3000);
</script>
"""


def find_chromium() -> str | None:
    return next((path for path in map(shutil.which, CHROMIUM_NAMES) if path), None)


def _probe(page: Path, chromium: str, workdir: Path, expression: str):
    """Opens a copy of `page` with a script that, once the scene is built, evaluates the
    JavaScript `expression` and writes it into the DOM as JSON; returns its value."""
    text = page.read_text()
    end = text.rfind("</body>")
    probe = workdir / "probe.html"
    probe.write_text(text[:end] + _PROBE % expression + text[end:])
    result = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", f"--user-data-dir={workdir / 'profile'}",
         "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
        capture_output=True, text=True, timeout=240, check=False)
    match = re.search(r'<pre id="physcap-probe">(.*?)</pre>', result.stdout, re.S)
    if match is None:
        raise AssertionError(f"the page did not report back; chromium exit "
                             f"{result.returncode}, stderr tail: {result.stderr[-800:]}")
    content = html.unescape(match.group(1))
    if content.startswith("ERROR"):
        raise AssertionError(f"the page's script failed: {content}")
    return json.loads(content)


def page_value(page: Path, chromium: str, workdir: Path, expression: str):
    """The value of the JavaScript `expression` in `page` once its scene is built; the
    expression may call physcapSceneNames(viewer.scene_tree, 0)."""
    return _probe(page, chromium, workdir, expression)


def meshcat_scene_tree(page: Path, chromium: str, workdir: Path) -> dict:
    """The nested names of the Meshcat scene that `page` builds in a browser."""
    return _probe(page, chromium, workdir, "physcapSceneNames(viewer.scene_tree, 0)")


def meshcat_image(page: Path, chromium: str, workdir: Path, size: tuple[int, int]):
    """What Meshcat's camera shows of `page`'s scene in a `size` (width, height) view, as a
    BGR image (numpy), rendered by the page's own viewer (`capture_image`)."""
    import cv2  # noqa: PLC0415 (only the image tests need it)
    import numpy as np  # noqa: PLC0415

    data_url = _probe(page, chromium, workdir, f"viewer.capture_image({size[0]}, {size[1]})")
    png = base64.b64decode(data_url.split(",", 1)[1])
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def meshcat_visibility(page: Path, path: str) -> set[bool]:
    """The values a Meshcat HTML file's commands give the `visible` property of `path`
    (decoded from the msgpack commands the page carries: 0xc2 is false, 0xc3 true)."""
    commands = b"".join(base64.b64decode(blob) for blob in re.findall(
        r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", page.read_text()))
    visible = re.escape(path.encode()) + rb"\xa8property\xa7visible\xa5value([\xc2\xc3])"
    return {value == b"\xc3" for value in re.findall(visible, commands)}
