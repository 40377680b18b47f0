#!/usr/bin/env python3
"""CPU and wall time of writing a new 4 MiB file (a 512 x 512 RGBA float32 frame), synced as
volcast syncs each image: through the page cache with write(2) calls of each size, and around
it (O_DIRECT, one call from an aligned buffer, as crates/volcast-render/src/output/write.rs writes whole files from
256 KiB). Medians of 15 files per way, in three rounds a few seconds apart. Not part of CI.

On this project's virtual machines (Linux 6.18 guests that hand free memory back to their
host) writes through the page cache take 1-3 ms of CPU per file in some spells and 20-35 ms
in others: calls of 256 KiB and more were slow in almost every round, calls of 16 and 64 KiB
in some rounds only (2026-12-05: one of three rounds each), while the direct write took
0.20-0.22 ms of CPU and 1.5 ms of wall time in every round.

Usage: python3 bench/write_pieces.py [DIR]   (DIR: a folder on the file system to measure,
default a new folder under the system's temporary folder; the files are removed)"""
import mmap
import os
import resource
import shutil
import statistics
import sys
import tempfile
import time


def cpu_ms():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return (r.ru_utime + r.ru_stime) * 1e3


def main():
    base = tempfile.mkdtemp(dir=sys.argv[1] if len(sys.argv) > 1 else None)
    # page-aligned, as O_DIRECT needs
    buf = mmap.mmap(-1, 4 << 20)
    buf.write(os.urandom(4 << 20))
    data = memoryview(buf)
    ways = [(f"{p >> 10} KiB writes", p) for p in [16 << 10, 64 << 10, 256 << 10, 4 << 20]]
    ways.append(("direct, one write", None))
    try:
        for rnd in range(3):
            for name, piece in ways:
                cpu, wall = [], []
                for i in range(15):
                    start, w0 = cpu_ms(), time.perf_counter()
                    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL
                    if piece is None:
                        flags |= os.O_DIRECT
                    fd = os.open(os.path.join(base, f"{rnd}_{name}_{i}"), flags)
                    if piece is None:
                        os.write(fd, data)
                    else:
                        for at in range(0, len(data), piece):
                            os.write(fd, data[at:at + piece])
                    os.fsync(fd)
                    os.close(fd)
                    cpu.append(cpu_ms() - start)
                    wall.append((time.perf_counter() - w0) * 1e3)
                print(f"round {rnd + 1}, {name:>17}: {statistics.median(cpu):6.2f} ms CPU "
                      f"(most {max(cpu):6.2f}), {statistics.median(wall):6.2f} ms wall per 4 MiB file")
            time.sleep(3)
    finally:
        shutil.rmtree(base)


if __name__ == "__main__":
    main()
