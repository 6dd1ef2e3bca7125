#!/usr/bin/python3
"""A stand-in for an STM32's serial bootloader (ST AN3155: the USART protocol) on a pty, for
scripts/flash --tool stm32flash without a board. It answers Get, Get Version, Get ID, Read
Memory, Write Memory, Extended Erase and Go as the ROM bootloader does, over a flash of the
given size that starts erased (0xFF), and after every write or erase leaves the whole flash in
--dump, so a test can compare what stm32flash wrote or boot it in QEMU.

  fake_stm32_bootloader.py --link PATH --pid 0x435 --flash-size 262144 --pages 2048 --dump FILE
  (--pages: the erase unit in bytes, one size for every page, or a comma list of sizes in order
  for sectors, e.g. an F405's 16384,16384,16384,16384,65536,131072,...)

PATH becomes a symlink to the pty's device; the fake runs until it is killed. With --silent it
reads and never answers, as a port with no board (or BOOT0 low) does.
"""
import argparse
import os
import sys
import termios
import tty

ACK, NACK = 0x79, 0x1F
BASE = 0x08000000
COMMANDS = [0x00, 0x01, 0x02, 0x11, 0x21, 0x31, 0x44]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--pid", required=True, type=lambda s: int(s, 0))
    ap.add_argument("--flash-size", required=True, type=int)
    ap.add_argument("--pages", required=True)
    ap.add_argument("--dump", required=True)
    ap.add_argument("--silent", action="store_true")
    a = ap.parse_args()
    sizes = [int(x) for x in a.pages.split(",")]
    pages = []  # (start offset, size)
    at = 0
    while at < a.flash_size:
        size = sizes[min(len(pages), len(sizes) - 1)]
        pages.append((at, size))
        at += size
    flash = bytearray(b"\xff" * a.flash_size)

    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    if os.path.lexists(a.link):
        os.unlink(a.link)
    os.symlink(os.ttyname(slave), a.link)

    def read(n):
        out = b""
        while len(out) < n:
            chunk = os.read(master, n - len(out))
            if not chunk:
                sys.exit(0)
            out += chunk
        return out

    def send(*data):
        os.write(master, bytes(data))

    def dump():
        tmp = a.dump + ".tmp"
        with open(tmp, "wb") as f:
            f.write(flash)
        os.replace(tmp, a.dump)

    def checked(data):  # the bytes, then their XOR; None when the checksum fails
        body = read(data)
        x = 0
        for b in body:
            x ^= b
        # A single byte is followed by its complement, several by their XOR.
        if read(1)[0] != ((x ^ 0xFF) if data == 1 else x):
            send(NACK)
            return None
        return body

    def address():
        body = checked(4)
        if body is None:
            return None
        addr = int.from_bytes(body, "big")
        if not BASE <= addr < BASE + a.flash_size:
            send(NACK)
            return None
        send(ACK)
        return addr - BASE

    dump()
    while a.silent:
        read(1)
    while True:
        cmd = read(1)[0]
        if cmd == 0x7F:  # the init byte (auto-baud)
            send(ACK)
            continue
        if read(1)[0] != cmd ^ 0xFF:
            send(NACK)
            continue
        if cmd not in COMMANDS:
            send(NACK)
            continue
        send(ACK)
        if cmd == 0x00:  # Get: version and the commands
            send(len(COMMANDS), 0x31, *COMMANDS, ACK)
        elif cmd == 0x01:  # Get Version and read protection
            send(0x31, 0x00, 0x00, ACK)
        elif cmd == 0x02:  # Get ID
            send(1, a.pid >> 8, a.pid & 0xFF, ACK)
        elif cmd == 0x11:  # Read Memory
            off = address()
            if off is None:
                continue
            n = checked(1)
            if n is None:
                continue
            send(ACK)
            os.write(master, bytes(flash[off:off + n[0] + 1]))
        elif cmd == 0x21:  # Go
            address()
        elif cmd == 0x31:  # Write Memory: only to erased bytes, as flash is programmed
            off = address()
            if off is None:
                continue
            n = read(1)[0] + 1
            data = read(n)
            x = (n - 1)
            for b in data:
                x ^= b
            if read(1)[0] != x or any(flash[off + i] != 0xFF and flash[off + i] != b for i, b in enumerate(data)):
                send(NACK)
                continue
            flash[off:off + n] = data
            dump()
            send(ACK)
        elif cmd == 0x44:  # Extended Erase: a page list (0xFFFx: special erases are refused)
            head = read(2)
            count = int.from_bytes(head, "big")
            if count >= 0xFFF0:
                read(1)
                send(NACK)
                continue
            body = read(2 * (count + 1))
            x = head[0] ^ head[1]
            for b in body:
                x ^= b
            if read(1)[0] != x:
                send(NACK)
                continue
            for i in range(count + 1):
                p = int.from_bytes(body[2 * i:2 * i + 2], "big")
                if p >= len(pages):
                    send(NACK)
                    break
                start, size = pages[p]
                flash[start:start + size] = b"\xff" * size
            else:
                dump()
                send(ACK)


if __name__ == "__main__":
    main()
