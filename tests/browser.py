"""Opening a Meshcat HTML file in headless Chromium and reading back what its scene shows.

`./run test` installs Chromium from the Debian packages when it is missing. The page's own
script runs (WebGL through SwiftShader) in a copy of the page with a small script added at the
top of its head; over the DevTools protocol (`--remote-debugging-pipe`), JavaScript expressions
are evaluated once the scene is built (every command the page carries handled), and Chromium
is closed at once (docs/development.md, "CPU cuts of the fourth session (headless Chromium)").
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import time
from pathlib import Path

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
TIMEOUT_S = 240.0
# WebGL through SwiftShader; a 64 × 48 window: the page's render loop draws little, and
# images are drawn at the size asked for (`capture_image`), whatever the window.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--window-size=64,48")

# Counts the page's command fetches and the commands its viewer has handled; the scene is
# built when the document is loaded and every fetched command is handled.
_READY = """<script>
window.physcapScene = {fetched: 0, handled: 0};
(function () {
  const fetchData = window.fetch;
  window.fetch = function (url, ...rest) {
    if (String(url).startsWith("data:application/octet-binary")
        && physcapScene.fetched++ === 0) {  // the viewer exists from the first fetch on
      const viewer = MeshCat.Viewer.prototype, handle = viewer.handle_command_bytearray;
      viewer.handle_command_bytearray = function (bytes) {
        try { return handle.call(this, bytes); } finally { physcapScene.handled++; }
      };
    }
    return fetchData.call(this, url, ...rest);
  };
})();
function physcapSceneNames(node, depth) {
  const names = {};
  if (depth > 5) return names;
  for (const [name, child] of Object.entries(node.children || {}))
    names[name] = physcapSceneNames(child, depth + 1);
  return names;
}
function physcapSceneBuilt(timeoutMs) {
  const until = Date.now() + timeoutMs;
  return new Promise(function (resolve, reject) {
    (function poll() {
      const scene = window.physcapScene;
      if (document.readyState === "complete" && scene.fetched > 0
          && scene.handled === scene.fetched) resolve();
      else if (Date.now() > until)
        reject(new Error("the scene was not built in time: " + JSON.stringify(scene)));
      else setTimeout(poll, 20);
    })();
  });
}
</script>
"""


def find_chromium() -> str | None:
    return next((path for path in map(shutil.which, CHROMIUM_NAMES) if path), None)


class MeshcatPage:
    """One headless Chromium showing a copy of the Meshcat page `page`; `value` evaluates
    JavaScript there once the scene is built. Use as a context manager (closes Chromium)."""

    def __init__(self, page: Path, chromium: str, workdir: Path):
        text = page.read_text()
        head = text.find("<head>")
        if head < 0:
            raise ValueError(f"{page}: not a Meshcat page (no <head>)")
        probe = workdir / "probe.html"
        probe.write_text(text[:head + 6] + _READY + text[head + 6:])
        self._deadline = time.monotonic() + TIMEOUT_S
        self._stderr = workdir / "chromium.stderr"
        self._launch(chromium, workdir, probe.as_uri())
        self._ids, self._buffer = 0, b""
        try:
            while not (tabs := [target["targetId"] for target in self._send(
                    "Target.getTargets")["targetInfos"] if target["type"] == "page"]):
                self._wait_a_little("the copy of the page was never opened")
            self._session = self._send("Target.attachToTarget", targetId=tabs[0],
                                       flatten=True)["sessionId"]
            while not self._probe_script_runs():
                self._wait_a_little("the copy's script never ran")
        except BaseException:
            self.close()
            raise

    def _wait_a_little(self, why: str) -> None:
        if time.monotonic() > self._deadline:
            raise self._fail(f"{why} in {TIMEOUT_S:.0f} s")
        time.sleep(0.05)

    def _probe_script_runs(self) -> bool:
        """Whether the copy's script has run (not yet while Chromium still loads it)."""
        try:
            return self._evaluate("typeof physcapSceneBuilt") == "function"
        except AssertionError:  # no page yet to run it in
            return False

    def _launch(self, chromium: str, workdir: Path, url: str) -> None:
        # Chromium reads the protocol's commands from fd 3 and writes its replies to fd 4.
        commands, replies = os.pipe(), os.pipe()
        theirs = [fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in (commands[0], replies[1])]
        for fd in (commands[0], replies[1]):
            os.close(fd)
        self._to, self._from = commands[1], replies[0]
        with open(self._stderr, "w") as stderr:
            self._process = subprocess.Popen(
                ["/bin/bash", "-c", f'exec "$@" 3<&{theirs[0]} 4>&{theirs[1]} '
                 f'{theirs[0]}<&- {theirs[1]}>&-', "chromium", chromium,
                 *CHROMIUM_FLAGS, f"--user-data-dir={workdir / 'profile'}",
                 "--remote-debugging-pipe", url],
                pass_fds=theirs, stdout=subprocess.DEVNULL, stderr=stderr)
        for fd in theirs:
            os.close(fd)

    def _fail(self, why: str) -> AssertionError:
        tail = self._stderr.read_text()[-800:] if self._stderr.exists() else ""
        return AssertionError(f"{why}; chromium exit {self._process.poll()}, "
                              f"stderr tail: {tail}")

    def _send(self, method: str, session: str | None = None, **params):
        self._ids += 1
        message = {"id": self._ids, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        try:
            os.write(self._to, json.dumps(message).encode() + b"\0")
        except BrokenPipeError:
            raise self._fail(f"chromium is gone: it did not take {method}") from None
        while True:
            while b"\0" not in self._buffer:
                left = self._deadline - time.monotonic()
                if left <= 0 or not select.select([self._from], [], [], left)[0]:
                    raise self._fail(f"the page did not answer {method} in {TIMEOUT_S:.0f} s")
                chunk = os.read(self._from, 1 << 20)
                if not chunk:
                    raise self._fail(f"chromium closed the pipe awaiting {method}")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._ids:  # else an event: not asked for
                if "error" in reply:
                    raise self._fail(f"{method}: {reply['error']}")
                return reply["result"]

    def _evaluate(self, expression: str):
        result = self._send("Runtime.evaluate", self._session, expression=expression,
                            awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            raise AssertionError("the page's script failed: "
                                 + details.get("exception", {}).get("description",
                                                                    details["text"]))
        return result["result"].get("value")

    def value(self, expression: str):
        """The value of the JavaScript `expression` once the scene is built; it may call
        physcapSceneNames(viewer.scene_tree, 0)."""
        budget_ms = max(0.0, self._deadline - time.monotonic() - 5.0) * 1000
        return json.loads(self._evaluate(
            f"physcapSceneBuilt({budget_ms:.0f}).then(() => JSON.stringify({expression}))"))

    def scene_tree(self) -> dict:
        """The nested names of the Meshcat scene the page builds."""
        return self.value("physcapSceneNames(viewer.scene_tree, 0)")

    def image(self, size: tuple[int, int]):
        """What Meshcat's camera shows of the scene in a `size` (width, height) view, as a
        BGR image (numpy), rendered by the page's own viewer (`capture_image`)."""
        import cv2  # noqa: PLC0415 (only the image tests need it)
        import numpy as np  # noqa: PLC0415

        data_url = self.value(f"viewer.capture_image({size[0]}, {size[1]})")
        png = base64.b64decode(data_url.split(",", 1)[1])
        return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)

    def close(self) -> None:
        try:
            self._send("Browser.close")
        except AssertionError:
            pass  # already gone
        try:
            self._process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()
        os.close(self._to)
        os.close(self._from)

    def __enter__(self) -> MeshcatPage:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def page_value(page: Path, chromium: str, workdir: Path, expression: str):
    """The value of the JavaScript `expression` in `page` once its scene is built; the
    expression may call physcapSceneNames(viewer.scene_tree, 0)."""
    with MeshcatPage(page, chromium, workdir) as shown:
        return shown.value(expression)


def meshcat_scene_tree(page: Path, chromium: str, workdir: Path) -> dict:
    """The nested names of the Meshcat scene that `page` builds in a browser."""
    with MeshcatPage(page, chromium, workdir) as shown:
        return shown.scene_tree()


def meshcat_images(page: Path, chromium: str, workdir: Path, sizes: list[tuple[int, int]]):
    """What Meshcat's camera shows of `page`'s scene in views of each of `sizes` (width,
    height), as BGR images, from one Chromium run."""
    with MeshcatPage(page, chromium, workdir) as shown:
        return [shown.image(size) for size in sizes]


def meshcat_visibility(page: Path, path: str) -> set[bool]:
    """The values a Meshcat HTML file's commands give the `visible` property of `path`
    (decoded from the msgpack commands the page carries: 0xc2 is false, 0xc3 true)."""
    commands = b"".join(base64.b64decode(blob) for blob in re.findall(
        r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", page.read_text()))
    visible = re.escape(path.encode()) + rb"\xa8property\xa7visible\xa5value([\xc2\xc3])"
    return {value == b"\xc3" for value in re.findall(visible, commands)}
