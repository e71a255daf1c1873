#!/usr/bin/env python3
"""Issue [shield]'s hostile rows again, through deploy/nginx.conf in front of
`linecloud serve` (scripts/fault_test.sh starts both; this gets nginx's port).
Raw requests on sockets, each answered with a documented status; dribbling
clients do not starve others and nginx closes them (client_header_timeout).
Usage: nginx_hostile.py PORT [MAP] [BODY.json]. Exits 1 naming every row that failed."""
import socket
import sys
import threading
import time

PORT = int(sys.argv[1])
MAP = sys.argv[2] if len(sys.argv) > 2 else "fountain"
BODY = open(sys.argv[3], "rb").read() if len(sys.argv) > 3 else b""  # a client-features body
HOST = "Host: 127.0.0.1\r\nConnection: close\r\n"
failures = []


def read_until_close(s):
    """What the server sends until it closes (or the socket's timeout); closes the socket."""
    raw = b""
    try:
        while chunk := s.recv(65536):
            raw += chunk
    except OSError:
        pass
    s.close()
    return raw


def exchange(data, timeout=15):
    """Sends bytes, reads the answer until the server closes; (status, head, body, seconds)."""
    start = time.monotonic()
    s = socket.create_connection(("127.0.0.1", PORT), timeout=timeout)
    try:
        s.sendall(data)
    except OSError:
        pass  # answered and closed before reading everything
    raw = read_until_close(s)
    head, _, body = raw.partition(b"\r\n\r\n")
    try:
        status = int(head.split(b" ")[1])
    except (IndexError, ValueError):
        status = 0
    return status, head, body, time.monotonic() - start


def row(name, data, allowed, max_body=None):
    status, _, body, seconds = exchange(data)
    ok = status in allowed and (max_body is None or len(body) <= max_body)
    print(f"{'ok  ' if ok else 'FAIL'} {name}: {status} ({len(body)} bytes, {seconds:.2f} s)")
    if not ok:
        failures.append(f"{name}: {status}, expected {sorted(allowed)}")


path = f"/v1/maps/{MAP}/localize"
nested = b"[" * 150000 + b"]" * 150000
row("1 nested JSON 150 000 deep",
    f"POST {path} HTTP/1.1\r\n{HOST}Content-Type: application/json\r\n"
    f"Content-Length: {len(nested)}\r\n\r\n".encode() + nested, {400})
row("2 500 ranges on a console file",
    f"GET / HTTP/1.1\r\n{HOST}Range: bytes=0-0{',0-' * 500}\r\n\r\n".encode(), {416}, 1024)
chunk = b"a" * 65536
chunked = b"".join(b"%x\r\n" % len(chunk) + chunk + b"\r\n" for _ in range(300))
row("3 chunked body of 19 MB (over client_max_body_size)",
    f"POST {path} HTTP/1.1\r\n{HOST}Transfer-Encoding: chunked\r\n\r\n".encode() + chunked, {413})
row("3b Content-Length 99 999 999 999",
    f"POST {path} HTTP/1.1\r\n{HOST}Content-Length: 99999999999\r\n\r\n".encode(), {413})
headers = "".join(f"X-{i}: {i}\r\n" for i in range(500))
row("5 500 header fields", f"GET /healthz HTTP/1.1\r\n{HOST}{headers}\r\n".encode(), {431, 400})
row("13 a NUL in the path", f"GET /app.js%00.html HTTP/1.1\r\n{HOST}\r\n".encode(), {400})
row("15 PUT on a POST route", f"PUT {path} HTTP/1.1\r\n{HOST}\r\n".encode(), {405})
row("— a 100 KB URI", f"GET /{'a' * 100000} HTTP/1.1\r\n{HOST}\r\n".encode(), {414})
row("— TLS bytes", b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03 \r\n\r\n", {400})
# The console's files are the folder's only: an absolute path (//etc/passwd was
# served by the server itself) or an encoded one.
for p in ("//etc/passwd", "/%2Fetc/passwd", "/%2e%2e/%2e%2e/etc/passwd"):
    row(f"— static path {p}", f"GET {p} HTTP/1.1\r\n{HOST}\r\n".encode(), {404, 400})
# Row 8: a JPEG header declaring 7000 x 7000 pixels in a few hundred bytes.
bomb = (b"\xFF\xD8\xFF\xC0\x00\x11\x08\x1B\x58\x1B\x58\x03\x01\x22\x00\x02\x11"
        b"\x01\x03\x11\x01\xFF\xDA\x00\x0C\x03\x01\x00\x02\x11\x03\x11\x00\x3F\x00"
        + b"\x55" * 300 + b"\xFF\xD9")
form = (b"--B\r\nContent-Disposition: form-data; name=\"image\"; filename=\"a.jpg\"\r\n\r\n" + bomb +
        b"\r\n--B\r\nContent-Disposition: form-data; name=\"camera\"\r\n\r\n"
        b"PINHOLE 7000 7000 5000 5000 3500 3500\r\n--B--\r\n")
row("8 a 7000 x 7000 JPEG header in 338 bytes",
    f"POST {path} HTTP/1.1\r\n{HOST}Content-Type: multipart/form-data; boundary=B\r\n"
    f"Content-Length: {len(form)}\r\n\r\n".encode() + form, {400})
# 16 MB of empty arrays (+400 MB to parse before the value count).
empties = b'{"keypoints":[' + b"[]," * 500000 + b"0]}"
row("— 500 000 empty JSON arrays",
    f"POST {path} HTTP/1.1\r\n{HOST}Content-Type: application/json\r\n"
    f"Content-Length: {len(empties)}\r\n\r\n".encode() + empties, {400})
# Row 14: two requests in one write (nginx answers both, in order).
s = socket.create_connection(("127.0.0.1", PORT), timeout=15)
s.sendall(b"GET /healthz HTTP/1.1\r\nHost: a\r\n\r\nGET /readyz HTTP/1.1\r\nHost: a\r\n"
          b"Connection: close\r\n\r\n")
answers = read_until_close(s).count(b"HTTP/1.1 200")
print(f"{'ok  ' if answers == 2 else 'FAIL'} 14 two pipelined requests: {answers} answered 200")
if answers != 2:
    failures.append(f"14 pipelining: {answers} of 2 answered")

# Row 4: 200 sockets dribbling header lines, from 10 addresses (127.0.0.2-11:
# 20 each, under the per-address limit); others answered meanwhile; nginx
# closes the dribblers at client_header_timeout.
dribblers = []
for i in range(200):
    s = socket.create_connection(("127.0.0.1", PORT), timeout=30,
                                 source_address=(f"127.0.0.{2 + i % 10}", 0))
    s.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    dribblers.append(s)
closed = []
stop = threading.Event()


def dribble():
    start = time.monotonic()
    while not stop.is_set() and dribblers and time.monotonic() - start < 25:
        for s in list(dribblers):
            try:
                s.sendall(b"X-Slow: y\r\n")
            except OSError:
                dribblers.remove(s)
                closed.append(time.monotonic() - start)
        time.sleep(1)


t = threading.Thread(target=dribble)
t.start()
time.sleep(2)
for i in range(5):
    status, _, _, seconds = exchange(f"GET /healthz HTTP/1.1\r\n{HOST}\r\n".encode())
    ok = status == 200 and seconds < 2
    print(f"{'ok  ' if ok else 'FAIL'} 4 request {i} while 200 clients dribble: {status} in {seconds:.2f} s")
    if not ok:
        failures.append(f"4: request {i} answered {status} in {seconds:.2f} s")
t.join()
ok = len(closed) == 200
print(f"{'ok  ' if ok else 'FAIL'} 4 dribblers closed by nginx: {len(closed)} of 200"
      + (f" (after {min(closed):.0f}-{max(closed):.0f} s)" if closed else ""))
if not ok:
    failures.append(f"4: {200 - len(closed)} dribblers still open after 25 s")
for s in dribblers:
    s.close()

# One address sending 40 localizations at once: nginx passes 32 on
# (limit_conn counts requests whose head was read), refuses the rest 503.
if BODY:
    request = (f"POST {path} HTTP/1.1\r\n{HOST}Content-Type: application/json\r\n"
               f"Content-Length: {len(BODY)}\r\n\r\n").encode() + BODY
    held = []
    for _ in range(40):
        s = socket.create_connection(("127.0.0.1", PORT), timeout=60,
                                     source_address=("127.0.0.20", 0))
        s.sendall(request)
        held.append(s)
    statuses = []
    for s in held:
        head, _, body = read_until_close(s).partition(b"\r\n\r\n")
        status = (head.split(b" ")[1:2] or [b"0"])[0].decode()
        statuses.append(status + (" nginx" if b"<center>nginx" in body else ""))
    refused = statuses.count("503 nginx")
    ok = refused >= 8 and statuses.count("200") + refused == 40
    print(f"{'ok  ' if ok else 'FAIL'} one address, 40 localizations at once: "
          f"{refused} refused by nginx (limit 32), {statuses.count('200')} answered 200")
    if not ok:
        failures.append(f"per-address limit: {sorted(statuses)}")

if failures:
    print("hostile rows through nginx FAILED:\n  " + "\n  ".join(failures))
    sys.exit(1)
print("hostile rows through nginx: all answered as documented")
