"""`vge app` and `vge play` listen on this machine only unless asked, and warn when asked.

Both tests start the real server and read what the kernel says it listens on
(`/proc/net/tcp` and `/proc/net/tcp6`: local address and state of every socket).
"""

from __future__ import annotations

import errno
import ipaddress
import socket
from pathlib import Path

import pytest

from .streamlit_browser import AppServer

LISTEN = "0A"


def listening_addresses(port: int) -> list[ipaddress.IPv4Address | ipaddress.IPv6Address]:
    """Local addresses of the sockets listening on `port`, from the kernel's tables."""
    found = []
    for table, width in (("/proc/net/tcp", 4), ("/proc/net/tcp6", 16)):
        lines = Path(table).read_text().splitlines()[1:]
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            address, _, hex_port = local.partition(":")
            if state != LISTEN or int(hex_port, 16) != port:
                continue
            raw = bytes.fromhex(address)
            # The kernel prints each 32-bit word in host (little-endian) order.
            words = [raw[i : i + 4][::-1] for i in range(0, width, 4)]
            packed = b"".join(words)
            found.append(ipaddress.ip_address(packed))
    return found


def outbound_address() -> str | None:
    """This host's address towards the network (no packet is sent), if it has a route."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.255", 9))
        except OSError:
            return None
        address = s.getsockname()[0]
    return None if ipaddress.ip_address(address).is_loopback else address


def test_the_dashboard_listens_on_loopback_only(app_server):
    addresses = listening_addresses(app_server.port)
    assert addresses, "nothing listens on the server's port"
    assert all(a.is_loopback for a in addresses), addresses
    with socket.create_connection(("127.0.0.1", app_server.port), timeout=5):
        pass
    other = outbound_address()
    if other is not None:  # this host has a network address: the dashboard is not on it
        with pytest.raises(OSError) as info, socket.socket() as s:
            s.settimeout(5)
            s.connect((other, app_server.port))
        assert info.value.errno == errno.ECONNREFUSED
    assert "warning" not in app_server.text()


def test_listening_on_all_interfaces_is_a_choice_with_a_warning(tiny_out, tmp_path):
    log = tmp_path / "vge-app.log"
    with AppServer(tiny_out, options=["--host", "0.0.0.0"], log=log) as server:
        addresses = listening_addresses(server.port)
        text = server.text()
    assert ipaddress.ip_address("0.0.0.0") in addresses, addresses
    assert (
        f"warning: listening on 0.0.0.0: anyone who can reach this machine on port "
        f"{server.port} can read the logs and model outputs and run queries on the SQL page"
    ) in text


def test_vge_play_listens_on_loopback_only_unless_asked(play_server, tmp_path):
    addresses = listening_addresses(play_server.server.port)
    assert addresses and all(a.is_loopback for a in addresses), addresses
    assert "warning" not in play_server.server.text()
    run = tmp_path / "open-run"
    options = ["--out", str(run), "--host", "0.0.0.0"]
    log = tmp_path / "vge-play-open.log"
    with AppServer(play_server.bench, command="play", options=options, log=log) as server:
        addresses = listening_addresses(server.port)
        text = server.text()
    assert ipaddress.ip_address("0.0.0.0") in addresses, addresses
    assert (
        f"warning: listening on 0.0.0.0: anyone who can reach this machine on port "
        f"{server.port} can play and write steps into {run.resolve()}"
    ) in text
