"""Where a live Rerun viewer is: ``--connect`` addresses, the spawned viewer's, and whether one listens.

No Rerun import: ``rose-bag process`` checks a ``--connect`` address before it loads Rerun.
"""

from __future__ import annotations

import socket
import urllib.parse

__all__ = [
    "SPAWNED_VIEWER",
    "ViewerLost",
    "ViewerNotStarted",
    "grpc_url",
    "viewer_endpoint",
    "viewer_unreachable",
]


def grpc_url(address: str) -> str:
    """A viewer address as Rerun's gRPC proxy URL.

    ``9876`` -> ``rerun+http://127.0.0.1:9876/proxy``; ``host:port`` -> ``rerun+http://host:port/proxy``;
    a full ``rerun+http(s)://...`` URL is kept.

    Raises
    ------
    ValueError
        If ``address`` is no viewer address: not a str (the port as an int failed with an
        AttributeError), no host, or a port not in 1..65535 (``99999`` and ``host:abc`` made URLs
        Rerun cannot use).
    """
    url = _proxy_url(address)
    viewer_endpoint(address)  # the host and port checked
    return url


def _proxy_url(address: str) -> str:
    """:func:`grpc_url` unchecked: the URL ``address`` stands for."""
    if not isinstance(address, str):
        msg = f"viewer address must be PORT, HOST:PORT or a rerun+http:// URL (a str), got {address!r}"
        raise ValueError(msg)
    text = address.strip()
    if text.startswith(("rerun://", "rerun+http://", "rerun+https://")):
        return text
    if text.isdigit():
        return f"rerun+http://127.0.0.1:{text}/proxy"
    if not text or "/" in text:
        msg = f"viewer address must be PORT, HOST:PORT or a rerun+http:// URL, got {address!r}"
        raise ValueError(msg)
    return f"rerun+http://{text}/proxy"


_VIEWER_PROBE_S = 3.0
"""Longest wait for a viewer to accept a connection before a session starts, seconds."""


#: Where the viewer that ``spawn`` starts listens (Rerun's default port, on this machine).
SPAWNED_VIEWER = "127.0.0.1:9876"


class ViewerNotStarted(RuntimeError):
    """The viewer :class:`RerunSink` spawned is not listening (it could not open a window)."""


class ViewerLost(RuntimeError):
    """The live viewer a recording streamed to went away (closed, killed) before the recording
    was finished; its file, if any, was written whole."""


def viewer_unreachable(address: str) -> str | None:
    """Why nothing accepts a connection at the viewer ``address`` (see :func:`grpc_url`), or None.

    Rerun's gRPC sink connects lazily and only fails at the final flush, after the whole session
    was processed; a TCP connection tried first turns a viewer that is not running into an error
    before any work.

    Raises
    ------
    ValueError
        If ``address`` is no viewer address (a bad port, no host).
    """
    host, port = viewer_endpoint(address)
    try:
        with socket.create_connection((host, port), timeout=_VIEWER_PROBE_S):
            return None
    except OSError as err:
        return str(err.strerror or err)


_LOCAL_HOSTS = frozenset({"localhost", "127.0.0.1", "::1"})


def viewer_endpoint(address: str) -> tuple[str, int]:
    """Host and TCP port Rerun connects to for ``address``: without a port, a local viewer's 9876,
    else the scheme's (``rerun+http``: 80; ``rerun`` and ``rerun+https``: 443, TLS), as Rerun does."""
    scheme, _, rest = _proxy_url(address).partition("://")
    parts = urllib.parse.urlsplit(f"//{rest}")
    host = parts.hostname
    try:
        port = parts.port
    except ValueError:  # out of range, or not a number
        port = 0
    if not host or port == 0 or parts.netloc.endswith(":"):  # "host:" names no port
        msg = f"viewer address needs a host and a port in 1..65535, got {address!r}"
        raise ValueError(msg)
    if port is None:
        port = 9876 if host in _LOCAL_HOSTS else 80 if scheme == "rerun+http" else 443
    return host, port
