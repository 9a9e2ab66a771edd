"""Opening a Meshcat HTML file in headless Chromium and listing the scene it builds.

`./run test` installs Chromium from the Debian packages when it is missing. The page's own
script runs (WebGL through SwiftShader); a small script added at the end of a copy of the page
writes the names of Meshcat's scene tree into the DOM, which `--dump-dom` prints.
"""

from __future__ import annotations

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
  out.id = "physcap-scene";
  try { out.textContent = JSON.stringify(physcapSceneNames(viewer.scene_tree, 0)); }
  catch (error) { out.textContent = "ERROR " + error; }
  document.body.appendChild(out);
}, 3000);
</script>
"""


def find_chromium() -> str | None:
    return next((path for path in map(shutil.which, CHROMIUM_NAMES) if path), None)


def meshcat_scene_tree(page: Path, chromium: str, workdir: Path) -> dict:
    """The nested names of the Meshcat scene that `page` builds in a browser."""
    text = page.read_text()
    end = text.rfind("</body>")
    probe = workdir / "probe.html"
    probe.write_text(text[:end] + _PROBE + text[end:])
    result = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", f"--user-data-dir={workdir / 'profile'}",
         "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
        capture_output=True, text=True, timeout=240, check=False)
    match = re.search(r'<pre id="physcap-scene">(.*?)</pre>', result.stdout, re.S)
    if match is None:
        raise AssertionError(f"the page did not report its scene; chromium exit "
                             f"{result.returncode}, stderr tail: {result.stderr[-800:]}")
    content = html.unescape(match.group(1))
    if content.startswith("ERROR"):
        raise AssertionError(f"the page's script failed: {content}")
    return json.loads(content)
