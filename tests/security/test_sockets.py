"""Localhost by default: a run's nodes bind no socket off loopback unless the experiment sets ``network: true``.

The runner gives the nodes contouring_ros/run/fastdds_profile.xml (shared memory, and UDPv4 whitelisted to
127.0.0.1 with unicast discovery to 127.0.0.1) and ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT, so that
rmw_fastrtps adds no transport of its own. While a run goes, every UDP and TCP socket of its node
processes is listed from /proc (the socket inodes of /proc/<pid>/fd, looked up in /proc/<pid>/net/udp,
udp6, tcp, tcp6) and must be bound to 127.0.0.1 or ::1. (Before: 32 sockets on 0.0.0.0 and 8 on the
machine's eth0 address for the process layout.)
"""
from __future__ import annotations

import os
import socket
import struct
import threading
import time
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.run.runner import FASTDDS_PROFILE, private_environment, run_graph
from contouring_ros.records.scoring import read_run
from conftest import DEFAULT, shortened

LOOPBACK = {"127.0.0.1", "::1"}
linux_only = pytest.mark.skipif(not os.path.isdir("/proc/self/net"), reason="reads /proc (Linux)")


def _address(text: str, v6: bool) -> str:
    raw = bytes.fromhex(text)
    if v6:      # four host-order 32-bit words
        return socket.inet_ntop(socket.AF_INET6, b"".join(struct.pack("<I", struct.unpack(">I", raw[i:i + 4])[0])
                                                          for i in range(0, 16, 4)))
    return socket.inet_ntop(socket.AF_INET, struct.pack("<I", int(text, 16)))


def inet_sockets(pid: int) -> set:
    """{(protocol, local address, port)} of every UDP/TCP socket that process ``pid`` holds open."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = set()
    for protocol in ("udp", "udp6", "tcp", "tcp6"):
        try:
            lines = Path(f"/proc/{pid}/net/{protocol}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if fields[9] in inodes:
                address, port = fields[1].split(":")
                found.add((protocol, _address(address, protocol.endswith("6")), int(port, 16)))
    return found


def sockets_during_run(path: Path, bag: Path, layout: str) -> tuple:
    """Run the experiment; return the names of its node processes and {(node, protocol, address, port)}
    seen while they ran."""
    seen, done, names = set(), threading.Event(), []

    def watch(nodes):
        while not done.is_set():
            for node in nodes:
                try:
                    seen.update((node.name, *entry) for entry in inet_sockets(node.process.pid))
                except OSError:         # the process has just exited
                    pass
            time.sleep(0.05)

    threads = []

    def started(nodes):
        names.extend(node.name for node in nodes)
        threads.append(threading.Thread(target=watch, args=(nodes,), daemon=True))
        threads[0].start()
    try:
        run_graph(path, bag, layout=layout, on_started=started)
    finally:
        done.set()
        for thread in threads:
            thread.join()
    return names, seen


def test_profiles_and_environment():
    """The localhost profile replaces the built-in transports by SHM and UDPv4 on 127.0.0.1; the runner
    lets it decide (SYSTEM_DEFAULT), and gives ``network: true`` runs the built-in transports."""
    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ElementTree.parse(FASTDDS_PROFILE).getroot()
    rtps = root.find("p:participant[@is_default_profile='true']/p:rtps", ns)
    assert rtps.find("p:useBuiltinTransports", ns).text.strip() == "false"
    used = [t.text.strip() for t in rtps.findall("p:userTransports/p:transport_id", ns)]
    descriptors = {d.find("p:transport_id", ns).text.strip(): d for d in root.findall(
        "p:transport_descriptors/p:transport_descriptor", ns)}
    assert sorted(descriptors[t].find("p:type", ns).text.strip() for t in used) == ["SHM", "UDPv4"]
    for transport in used:
        if descriptors[transport].find("p:type", ns).text.strip() == "UDPv4":
            allowed = [a.text.strip() for a in descriptors[transport].findall("p:interfaceWhiteList/p:address", ns)]
            assert allowed == ["127.0.0.1"]
    for where in ("p:builtin/p:metatrafficUnicastLocatorList", "p:builtin/p:initialPeersList"):
        assert [a.text.strip() for a in rtps.findall(where + "/p:locator/p:udpv4/p:address", ns)] == ["127.0.0.1"]

    saved = os.environ.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
    try:
        local, network = private_environment(7), private_environment(7, network=True)
    finally:
        if saved is not None:
            os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = saved
    assert local["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert local["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(FASTDDS_PROFILE)
    assert network["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    network_profile = Path(network["FASTRTPS_DEFAULT_PROFILES_FILE"])
    assert network_profile != FASTDDS_PROFILE and network_profile.is_file()
    assert ElementTree.parse(network_profile).getroot().find(".//p:useBuiltinTransports", ns) is None
    assert "ROS_LOCALHOST_ONLY" not in local and "ROS_STATIC_PEERS" not in local
    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"], kept = "/elsewhere/profile.xml", saved
    try:       # a profile of the user's own is kept, with rmw_fastrtps' LOCALHOST range
        own = private_environment(7)
    finally:
        if kept is None:
            del os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"]
        else:
            os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = kept
    assert own["FASTRTPS_DEFAULT_PROFILES_FILE"] == "/elsewhere/profile.xml"
    assert own["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


@linux_only
@pytest.mark.graph
@pytest.mark.parametrize("layout", ["process", "composed"])
def test_localhost_run_binds_nothing_off_loopback(layout, tmp_path):
    path = tmp_path / "local.yaml"
    path.write_text(shortened(DEFAULT, 0.5))
    names, seen = sockets_during_run(path, tmp_path / "local.mcap", layout)
    assert len(names) == (8 if layout == "process" else 1)
    assert {entry[0] for entry in seen} == set(names)      # every node process was seen with its sockets
    off_loopback = sorted(entry for entry in seen if entry[2] not in LOOPBACK)
    assert not off_loopback, f"{len(off_loopback)} of {len(seen)} sockets off loopback: {off_loopback[:10]}"


@linux_only
@pytest.mark.graph
def test_network_run_still_works(tmp_path):
    """``network: true`` binds on every interface (the built-in transports) and runs as before."""
    path = tmp_path / "network.yaml"
    path.write_text(shortened(DEFAULT, 0.3).replace("    sample_time: 0.001\n", "    sample_time: 0.001\n    network: true\n", 1))
    bag = tmp_path / "network.mcap"
    _, seen = sockets_during_run(path, bag, "composed")
    assert any(entry[2] not in LOOPBACK for entry in seen)
    expected = simulate(build_loop(load_experiment(path)))
    np.testing.assert_array_equal(read_run(bag).result.position, expected.position)
