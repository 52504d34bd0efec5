#!/usr/bin/env python3
"""An example policy for `carla-gs drive` (protocol carla-gs-drive/1, docs/drive.md).

Python standard library only. It speaks JSON lines over stdin/stdout:

  <- {"type": "hello", ...}            episode info: clock, cameras, route
  -> {"type": "ready", "name": ..., "ground_truth": bool}
  <- {"type": "tick", ...}             one per tick: ego state, camera PNG paths, maybe objects
  -> {"control": {"steer": s, "throttle": t, "brake": b}}
  <- {"type": "end", "reason": ...}

What it does: pure pursuit along the route (the logged ego path) at the speed it starts with,
and, with --ground-truth, brakes fully when an object in its lane is less than 2 s away. Every
tick it decodes the first camera's PNG (zlib from the standard library) and logs the image's
mean brightness on stderr every 10 ticks, to show how to read the frames.

Usage: carla-gs drive <run dir> ... --policy exec -- python3 tools/policy_example.py [--ground-truth]
"""

import json
import math
import struct
import sys
import zlib


def read_png_rgb(path):
    """Decodes an 8-bit RGB or RGBA PNG: (width, height, bytes of RGB rows)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, width, height, channels = 8, b"", 0, 0, 3
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            if depth != 8 or colour not in (2, 6):
                raise ValueError(f"{path}: only 8-bit RGB(A) PNGs are read here")
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    raw, stride = zlib.decompress(idat), width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind, line = raw[start], bytearray(raw[start + 1:start + 1 + stride])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b, c = prev[i], prev[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line) if channels == 3 else bytes(v for k, v in enumerate(line) if k % 4 != 3))
        prev = line
    return width, height, b"".join(rows)


def nearest(route, x, y):
    return min(range(len(route)), key=lambda i: (route[i][0] - x) ** 2 + (route[i][1] - y) ** 2)


def main():
    ground_truth = "--ground-truth" in sys.argv[1:]
    send = lambda msg: (sys.stdout.write(json.dumps(msg) + "\n"), sys.stdout.flush())
    hello = json.loads(sys.stdin.readline())
    route = hello["route"]
    wheelbase = 0.6 * hello["ego_size_lwh"][0]
    send({"type": "ready", "name": "python-example" + ("-gt" if ground_truth else ""), "ground_truth": ground_truth})
    target_speed = None
    for line in sys.stdin:
        msg = json.loads(line)
        if msg.get("type") == "end":
            break
        ego = msg["ego"]
        x, y, heading, v = ego["x"], ego["y"], ego["heading"], ego["speed"]
        if target_speed is None:
            target_speed = v
        images = [c["image"] for c in msg["cameras"] if c.get("image")]
        if images:
            w, h, rgb = read_png_rgb(images[0])
            if msg["tick"] % 10 == 0:
                print(f"tick {msg['tick']}: {w}x{h}, mean brightness {sum(rgb) / len(rgb):.1f}", file=sys.stderr)
        # Pure pursuit: the route point a look-ahead distance on from the nearest one.
        lookahead = max(5.0, v)
        i = nearest(route, x, y)
        while i + 1 < len(route) and math.hypot(route[i][0] - x, route[i][1] - y) < lookahead:
            i += 1
        dx, dy = route[i][0] - x, route[i][1] - y
        alpha = math.atan2(dy, dx) - heading
        alpha = math.atan2(math.sin(alpha), math.cos(alpha))
        delta = math.atan2(2.0 * wheelbase * math.sin(alpha), max(lookahead, 1e-3))
        steer = max(-1.0, min(1.0, -delta / 0.7))  # CARLA: + = right; about 0.7 rad at full lock
        error = target_speed - v
        throttle, brake = max(0.0, min(1.0, 0.5 * error)), max(0.0, min(1.0, -0.5 * error))
        if ground_truth:
            c, s = math.cos(heading), math.sin(heading)
            for o in msg.get("ground_truth", {}).get("objects", []):
                ahead = (o["x"] - x) * c + (o["y"] - y) * s
                across = -(o["x"] - x) * s + (o["y"] - y) * c
                closing = v - (o["vx"] * c + o["vy"] * s)
                gap = ahead - hello["ego_size_lwh"][0] / 2 - o["length"] / 2
                if ahead > 0 and abs(across) < 2.0 and closing > 0 and gap / closing < 2.0:
                    throttle, brake = 0.0, 1.0
        send({"control": {"steer": steer, "throttle": throttle, "brake": brake}})


if __name__ == "__main__":
    main()
