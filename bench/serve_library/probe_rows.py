#!/usr/bin/env python3
"""The rows cpp-httplib cannot close (issue [shield]), against any server on
127.0.0.1:PORT whose process is PID: bench/serve_library/mhd_probe.cc, or
`linecloud serve`. Prints what each row got; measures, asserts nothing.
Usage: probe_rows.py PORT PID [DRIBBLERS]"""
import socket
import sys
import threading
import time

PORT, PID = int(sys.argv[1]), int(sys.argv[2])
DRIBBLERS = int(sys.argv[3]) if len(sys.argv) > 3 else 2000


def status_of(proc_field):
    for line in open(f"/proc/{PID}/status"):
        if line.startswith(proc_field + ":"):
            return line.split()[1]
    return "?"


def exchange(data, timeout=10, source="127.0.0.1", half_close=True):
    start = time.monotonic()
    s = socket.create_connection(("127.0.0.1", PORT), timeout=timeout, source_address=(source, 0))
    try:
        s.sendall(data)
        if half_close:
            s.shutdown(socket.SHUT_WR)
    except OSError:
        pass
    raw = b""
    try:
        while chunk := s.recv(65536):
            raw += chunk
    except OSError:
        pass
    s.close()
    return raw, time.monotonic() - start


rss0 = status_of("VmRSS")
raw, sec = exchange(b"GET /healthz HTTP/1.1\r\nHost: a\r\n" + b"".join(
    b"X-%d: %d\r\n" % (i, i) for i in range(500000)) + b"\r\n", timeout=30)
print(f"row 5, 500 000 header fields: {raw[:12]!r} in {sec:.2f} s; "
      f"VmRSS {rss0} -> {status_of('VmRSS')} kB, VmHWM {status_of('VmHWM')} kB")
raw, _ = exchange(b"GET /healthz HTTP/1.1\r\nHost: a\r\n\r\nGET /healthz HTTP/1.1\r\nHost: a\r\n"
                  b"Connection: close\r\n\r\n", timeout=5, half_close=False)
print(f"row 14, two pipelined requests: {raw.count(b'HTTP/1.1 ')} answered")
raw, _ = exchange(b"GET /echo-authorization HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer%20secret\r\n"
                  b"Connection: close\r\n\r\n")
seen = raw.split(b"\r\n\r\n")[-1][:40]
print(f"Bearer%20: the server saw {seen!r}")

socks = []
for i in range(DRIBBLERS):
    try:
        s = socket.create_connection(("127.0.0.1", PORT), timeout=10,
                                     source_address=(f"127.0.{1 + i // 20 // 250}.{2 + (i // 20) % 250}", 0))
        s.sendall(b"GET /healthz HTTP/1.1\r\nHost: a\r\n")
        socks.append(s)
    except OSError:
        pass
stop = threading.Event()


def dribble():
    while not stop.is_set():
        for s in socks:
            try:
                s.sendall(b"X-Slow: y\r\n")
            except OSError:
                pass
        stop.wait(1)


t = threading.Thread(target=dribble)
t.start()
time.sleep(3)
times = []
for _ in range(10):
    # A legitimate client: it does not half-close (libmicrohttpd takes the end of
    # input as an abort when the answer is not written yet).
    raw, sec = exchange(b"GET /healthz HTTP/1.1\r\nHost: a\r\nConnection: close\r\n\r\n",
                        half_close=False)
    times.append((raw[:12], round(sec, 3)))
print(f"row 4, {len(socks)} sockets dribbling (20 per address): others got {times[:3]} ... "
      f"worst {max(t[1] for t in times)} s; threads {status_of('Threads')}, VmRSS {status_of('VmRSS')} kB")
stop.set()
t.join()
for s in socks:
    s.close()
held = [socket.create_connection(("127.0.0.1", PORT), timeout=5, source_address=("127.0.9.9", 0))
        for _ in range(40)]
time.sleep(0.5)
closed = 0
for s in held:
    s.setblocking(False)
    try:
        closed += s.recv(1) == b""
    except BlockingIOError:
        pass
    except OSError:
        closed += 1
    s.close()
print(f"one address opening 40 connections: {closed} closed at once")
