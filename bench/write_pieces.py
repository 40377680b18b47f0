#!/usr/bin/env python3
"""CPU time of writing a new 4 MiB file (a 512 x 512 RGBA float32 frame) with write(2) calls of
each size, median of 21 files per size. On this project's machines (Linux 6.18) calls of 256 KiB
and more (in some runs 128 KiB) took 20-38 ms per file and calls of 64 KiB 0.9-1.1 ms
(2026-12-05), which is why
src/output/write.rs hands the file 64 KiB at a time. Not part of CI.

Usage: python3 bench/write_pieces.py [DIR]   (DIR: a folder on the file system to measure,
default a new folder under the system's temporary folder; the files are removed)"""
import os
import resource
import shutil
import statistics
import sys
import tempfile


def cpu_ms():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return (r.ru_utime + r.ru_stime) * 1e3


def main():
    base = tempfile.mkdtemp(dir=sys.argv[1] if len(sys.argv) > 1 else None)
    data = memoryview(os.urandom(4 << 20))
    try:
        for piece in [4 << 10, 16 << 10, 64 << 10, 128 << 10, 256 << 10, 1 << 20, 4 << 20]:
            times = []
            for i in range(21):
                start = cpu_ms()
                fd = os.open(os.path.join(base, f"{piece}_{i}"), os.O_WRONLY | os.O_CREAT | os.O_EXCL)
                for at in range(0, len(data), piece):
                    os.write(fd, data[at:at + piece])
                os.close(fd)
                times.append(cpu_ms() - start)
            print(f"{piece >> 10:5d} KiB writes: {statistics.median(times):6.2f} ms CPU per 4 MiB file")
    finally:
        shutil.rmtree(base)


if __name__ == "__main__":
    main()
