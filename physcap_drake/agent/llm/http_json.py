"""One HTTP exchange with a model server, with the standard library, under a total deadline.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import copy
import http.client
import json
import ssl
import time
import urllib.parse
from typing import Any

from physcap_drake.agent.llm._common import LLMConfigError
from physcap_drake.agent.llm.base import LLMTimeout, TransientLLMError, one_line

#: The most bytes an answer may have (a chat completion is a few kilobytes).
MAX_BODY_BYTES = 8 * 1024 * 1024
_CHUNK = 64 * 1024


class Endpoint:
    """A server's base URL (e.g. http://localhost:8000/v1), split for http.client."""

    def __init__(self, base_url: str):
        parsed = urllib.parse.urlsplit(base_url.strip())
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise LLMConfigError(f"the server URL must look like http://host:port/v1; got "
                                 f"{base_url!r}")
        if parsed.query or parsed.fragment:
            raise LLMConfigError(f"the server URL may not carry a query or fragment: "
                                 f"{base_url!r}")
        self.url = base_url.strip().rstrip("/")
        self.https = parsed.scheme == "https"
        self.host = parsed.hostname
        try:
            self.port = parsed.port or (443 if self.https else 80)
        except ValueError as error:
            raise LLMConfigError(f"bad port in the server URL {base_url!r}: {error}") from None
        self.prefix = parsed.path.rstrip("/")

    def at_root(self) -> Endpoint:
        """The same server with no path prefix."""
        root = copy.copy(self)
        root.prefix = ""
        return root

    def connection(self, timeout_s: float) -> http.client.HTTPConnection:
        if self.https:
            return http.client.HTTPSConnection(self.host, self.port, timeout=timeout_s,
                                               context=ssl.create_default_context())
        return http.client.HTTPConnection(self.host, self.port, timeout=timeout_s)


class Reply:
    """An HTTP answer: status, headers (lower-case names) and the body as text."""

    def __init__(self, status: int, headers: dict[str, str], body: bytes):
        self.status = status
        self.headers = headers
        self.text = body.decode("utf-8", errors="replace")

    @property
    def content_type(self) -> str:
        return self.headers.get("content-type", "").split(";")[0].strip().lower()

    def json(self, where: str) -> Any:
        """The body decoded as JSON; TransientLLMError quoting the body if it is not JSON
        (an HTML error page from a proxy, a body cut short, ...)."""
        try:
            return json.loads(self.text)
        except ValueError as error:
            what = ("an HTML page" if self.text.lstrip()[:1] == "<" else
                    "cut short or not JSON" if self.text.lstrip()[:1] in "{[" else "not JSON")
            raise TransientLLMError(
                f"{where}: HTTP {self.status} but the body is {what} ({error}; content type "
                f"{self.content_type or 'not given'}): {one_line(self.text, 200)!r}") from None


def exchange(endpoint: Endpoint, method: str, path: str, body: dict[str, Any] | None,
             headers: dict[str, str], deadline_s: float, where: str,
             limit_s: float | None = None) -> Reply:
    """Sends one request to `endpoint.prefix + path` and reads the whole answer within
    `deadline_s` seconds in all. Raises LLMTimeout when the time is up (naming `limit_s`,
    the caller's whole limit, if given), TransientLLMError when the server cannot be reached
    or the connection breaks or the body is cut short."""
    start = time.monotonic()

    def left() -> float:
        remaining = deadline_s - (time.monotonic() - start)
        if remaining <= 0:
            raise TimeoutError
        return remaining

    payload = None if body is None else json.dumps(body).encode("utf-8")
    sent = {"Accept": "application/json", **headers}
    if payload is not None:
        sent["Content-Type"] = "application/json"
    connection = endpoint.connection(deadline_s)
    response = None
    received = 0
    try:
        connection.timeout = left()
        connection.connect()
        sock = connection.sock  # the response reads from it after the connection lets go
        sock.settimeout(left())
        connection.request(method, endpoint.prefix + path, body=payload, headers=sent)
        sock.settimeout(left())
        response = connection.getresponse()
        parts = []
        while True:
            sock.settimeout(left())
            chunk = response.read1(_CHUNK)
            if not chunk:
                break
            received += len(chunk)
            if received > MAX_BODY_BYTES:
                raise TransientLLMError(f"{where}: the answer is larger than "
                                        f"{MAX_BODY_BYTES // 1024 // 1024} MB; stopped reading")
            parts.append(chunk)
        if response.length:  # the connection closed before the announced length came
            raise http.client.IncompleteRead(b"".join(parts), response.length)
        return Reply(response.status, {k.lower(): v for k, v in response.getheaders()},
                     b"".join(parts))
    except TimeoutError:
        got = f"; {received} bytes of the answer had come" if received else ""
        raise LLMTimeout(f"{where}: no complete answer within {limit_s or deadline_s:g} s"
                         f"{got}") from None
    except http.client.IncompleteRead as error:
        raise TransientLLMError(f"{where}: the answer was cut short ({len(error.partial)} "
                                f"bytes came, more were announced)") from None
    except ConnectionRefusedError:
        raise TransientLLMError(f"{where}: connection refused (is the server running at "
                                f"{endpoint.url}?)") from None
    except ssl.SSLError as error:
        raise TransientLLMError(f"{where}: TLS failed: {error}") from None
    except (OSError, http.client.HTTPException) as error:
        raise TransientLLMError(f"{where}: the connection failed or broke: "
                                f"{type(error).__name__}: {one_line(str(error), 200)}") from None
    finally:
        if response is not None:
            response.close()
        connection.close()
