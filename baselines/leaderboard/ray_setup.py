"""Ray's address checked before a run joins it, and Ray's notes that ask nothing of the user.

Ray's note that its default token authentication is on (printed for every
cluster it starts) is kept out of the output; its warning that it is off stays.
"""

from __future__ import annotations

import logging
import socket

#: Ray's logger of the token authentication set-up.
_TOKEN_LOGGER = "ray._private.authentication.authentication_token_setup"


class NoRayCluster(ConnectionError):
    """Nothing answers at the Ray address given."""


def check_ray_address_form(address: str) -> tuple[str, int] | None:
    """The ``(host, port)`` of a Ray address, None for ``auto`` and ``local``.

    Raises:
        ValueError: When it has none of Ray's forms (``HOST:PORT``,
            ``ray://HOST:PORT``, ``auto``, ``local``).
    """
    if address in ("auto", "local"):
        return None
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"address {address!r}: expected HOST:PORT, ray://HOST:PORT, auto or local")
    return host, int(port)


def check_ray_address(address: str, timeout: float = 5.0) -> None:
    """Refuse an address Ray cannot take, or a ``host:port`` where no Ray listens.

    Ray would retry such a port for minutes; ``auto`` and ``local`` are left to
    it. A port that answers a plain HTTP request is a web server (most often
    Ray's dashboard), not Ray's gRPC.

    Raises:
        NoRayCluster: Naming the address, when its port takes no connection
            or a web server answers there.
        ValueError: When it has none of Ray's forms.
    """
    where = check_ray_address_form(address)
    if where is None:
        return
    host, port = where
    try:
        conn = socket.create_connection((host, port), timeout=timeout)
    except (OSError, ValueError) as exc:
        raise NoRayCluster(
            f"address {address}: no Ray cluster answers there ({exc}); start one with "
            "`ray start --head` or leave --address out for a local Ray"
        ) from None
    with conn:
        try:
            conn.sendall(b"HEAD / HTTP/1.0\r\n\r\n")
            reply = conn.recv(5)
        except OSError:  # connected, no answer to HTTP (a timeout): not a web server
            return
    if reply == b"HTTP/":
        raise NoRayCluster(
            f"address {address}: a web server answers there (Ray's dashboard?), not a Ray "
            "cluster: give the address `ray start --head` printed (HOST:6379 by default)"
        )


class _NotTheTokenNote(logging.Filter):
    """Drops Ray's note that token authentication is enabled (its default)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Token authentication is enabled")


_TOKEN_NOTE_FILTER = _NotTheTokenNote()


def quiet_token_note() -> None:
    """Keep Ray's "token authentication is enabled" note out of the output (once per process)."""
    logger = logging.getLogger(_TOKEN_LOGGER)
    if _TOKEN_NOTE_FILTER not in logger.filters:
        logger.addFilter(_TOKEN_NOTE_FILTER)
