"""Time of the ACL reply reader on a long reply fed one byte at a time (issue #15: the old reader
re-analysed the whole reply on every byte, 2.6 s for 4 KB, past the 2 s reply timeout).

Run: ``uv run python -m selfcal.benchmarks.timing.acl``.
"""

from __future__ import annotations

import time

from selfcal.hw.acl.reply import ReplyAssembler


def time_reply(n_bytes: int = 4096) -> tuple[int, float]:
    """Feed a LISTPV-like reply of about ``n_bytes`` one byte at a time; returns (bytes, seconds)."""
    lines, size, i = [], 0, 1
    while size < n_bytes:
        line = f"{i}:{i * 7}\r\n"
        lines.append(line)
        size += len(line)
        i += 1
    data = ("".join(lines) + ">").encode()
    asm = ReplyAssembler(None)
    t0 = time.perf_counter()
    for k in range(len(data)):
        asm.feed(data[k : k + 1])
    asm.result()
    return len(data), time.perf_counter() - t0


def main() -> None:
    for n in (4096, 16384, 65000):
        size, dt = time_reply(n)
        print(f"{size:6d} bytes byte by byte: {dt:.3f} s")


if __name__ == "__main__":
    main()
