"""The Fast DDS shared-memory files in /dev/shm: which ones a live process holds, and removing those a killed
node left behind (a node killed by a signal cannot release its segments)."""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["SHARED_MEMORY", "shared_memory_in_use", "clean_shared_memory"]

SHARED_MEMORY = Path("/dev/shm")


def shared_memory_in_use() -> set:
    """Every /dev/shm path some live process has open or mapped (from /proc; what we can read)."""
    held = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            for line in (proc / "maps").read_text().splitlines():
                if "/dev/shm/" in line:
                    held.add(line[line.index("/dev/shm/"):].split(" (deleted)")[0].strip())
            for fd in (proc / "fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("/dev/shm/"):
                    held.add(target)
        except OSError:
            continue
    return held


def clean_shared_memory(since: float) -> int:
    """Remove the Fast DDS shared-memory files a killed node left behind: created since ``since`` (a
    time.time()) and open or mapped by no live process. A node killed by a signal cannot release its
    segments, and stale ones pile up across runs and slow every later participant's start. Returns how
    many were removed."""
    if not SHARED_MEMORY.is_dir():
        return 0
    candidates = []
    for path in SHARED_MEMORY.iterdir():
        if "fastrtps" in path.name or "fastdds" in path.name:
            try:
                if path.stat().st_mtime >= since:
                    candidates.append(path)
            except OSError:
                continue
    if not candidates:
        return 0
    held, removed = shared_memory_in_use(), 0
    for path in candidates:
        if str(path) not in held:
            try:
                path.unlink()
                removed += 1
            except OSError:
                pass
    return removed
