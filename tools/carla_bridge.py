#!/usr/bin/env python3
"""carla-gs <-> CARLA bridge: JSON lines on stdin/stdout (protocol in docs/carla.md).

carla-gs (`sim::carla`) starts this process, sends one `setup` message, one `step` per control
period and a `close`; the bridge answers `ready`, one `state` per step and `closed`, or an
`error` at any point. Everything on the wire is in CARLA's own frame and units (left-handed:
x forward, y right, z up; metres; yaw in degrees, positive turning from +x towards +y; m/s):
carla-gs converts once, in `sim::carla::frame`, and this script converts nothing. Logs go to
stderr; stdout carries only protocol lines.

Modes:
  (default)  CARLA's official Python client (`carla==0.9.16`): loads the OpenDRIVE map in
             standalone mode, synchronous mode with a fixed step and physics sub-steps of at most
             0.01 s, spawns the adversary at its pose and speed, replays every other actor
             kinematically (physics off), attaches a collision sensor to the adversary, applies
             carla-gs's PID commands and ticks once per step.
  --fake     No CARLA: a kinematic bicycle with a first-order pedal lag stands in for the server,
             and oriented-box overlap stands in for the collision sensor. Same protocol, so the
             Rust side is tested end to end through a real pipe on machines without a server.
"""

import json
import math
import sys
import threading

PROTOCOL = 1
SUBSTEP_S = 0.01
MAX_SUBSTEPS = 10
# Blueprints for the replayed actors by carla-gs object class; static props for what does not move.
BLUEPRINTS = {
    "vehicle": "vehicle.lincoln.mkz_2020",
    "pedestrian": "walker.pedestrian.0001",
    "cyclist": "vehicle.bh.crossbike",
    "sign": "static.prop.streetsign",
    "other": "static.prop.box01",
}
# Actors are spawned this high above their pose (nothing to collide with up there), then moved
# into place with set_transform, which does not refuse overlaps the log may contain.
SPAWN_LIFT_M = 500.0


def log(*args):
    print("carla_bridge:", *args, file=sys.stderr, flush=True)


def send(msg):
    sys.stdout.write(json.dumps(msg, separators=(",", ":")) + "\n")
    sys.stdout.flush()


def error(kind, message):
    send({"type": "error", "kind": kind, "message": message})


class BridgeError(Exception):
    def __init__(self, kind, message):
        super().__init__(message)
        self.kind = kind


def box_corners(x, y, yaw_deg, length, width):
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    hl, hw = length / 2.0, width / 2.0
    return [(x + c * a - s * b, y + s * a + c * b) for a, b in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))]


def boxes_overlap(a, b):
    """Separating-axis test of two convex quadrilaterals (lists of 4 corners)."""
    for poly in (a, b):
        for i in range(4):
            (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % 4]
            nx, ny = y0 - y1, x1 - x0
            pa = [nx * px + ny * py for px, py in a]
            pb = [nx * px + ny * py for px, py in b]
            if max(pa) < min(pb) or max(pb) < min(pa):
                return False
    return True


class FakeWorld:
    """A kinematic bicycle (box centre, CARLA frame) with a first-order pedal lag."""

    A_MAX = 4.0  # m/s^2 at full throttle
    B_MAX = 8.0  # m/s^2 at full brake
    MAX_STEER_DEG = 70.0
    PEDAL_TAU_S = 0.25

    def __init__(self, setup):
        adv = setup["adversary"]
        t = adv["transform"]
        self.x, self.y, self.z, self.yaw = t["x"], t["y"], t["z"], t["yaw"]
        self.v = float(adv["speed_mps"])
        self.length, self.width = adv["size_lwh"][0], adv["size_lwh"][1]
        self.wheelbase = float(setup.get("wheelbase_m", 2.6))
        self.step_s = float(setup["step_s"])
        self.sizes = {a["id"]: a["size_lwh"] for a in setup["actors"]}
        self.pedal = 0.0
        self.delta = 0.0
        self.frame = 0
        self.vel = (self.v * math.cos(math.radians(self.yaw)), self.v * math.sin(math.radians(self.yaw)))

    def ready(self):
        return {"type": "ready", "protocol": PROTOCOL, "server_version": "fake (kinematic bicycle)",
                "map": "fake", "frame": self.frame}

    def step(self, msg):
        c = msg["control"]
        cmd = float(c["throttle"]) - float(c["brake"])
        n = max(1, int(math.ceil(self.step_s / SUBSTEP_S - 1e-9)))
        h = self.step_s / n
        yaw_before = self.yaw
        vel_before = self.vel
        for _ in range(n):
            self.pedal += (cmd - self.pedal) * (1.0 - math.exp(-h / self.PEDAL_TAU_S))
            a = self.pedal * (self.A_MAX if self.pedal >= 0 else self.B_MAX)
            self.v = max(0.0, self.v + a * h)
            self.delta = math.radians(float(c["steer"]) * self.MAX_STEER_DEG)
            yaw_rate = self.v / self.wheelbase * math.tan(self.delta)  # rad/s, positive = right
            self.yaw += math.degrees(yaw_rate * h)
            self.x += self.v * math.cos(math.radians(self.yaw)) * h
            self.y += self.v * math.sin(math.radians(self.yaw)) * h
        self.frame += 1
        self.vel = (self.v * math.cos(math.radians(self.yaw)), self.v * math.sin(math.radians(self.yaw)))
        acc = ((self.vel[0] - vel_before[0]) / self.step_s, (self.vel[1] - vel_before[1]) / self.step_s)
        mine = box_corners(self.x, self.y, self.yaw, self.length, self.width)
        collisions = []
        for a in msg["actors"]:
            size = self.sizes.get(a["id"])
            t = a["transform"]
            if size and boxes_overlap(mine, box_corners(t["x"], t["y"], t["yaw"], size[0], size[1])):
                collisions.append({"frame": self.frame, "other": a["id"], "other_type": "fake"})
        return {
            "type": "state",
            "frame": self.frame,
            "transform": {"x": self.x, "y": self.y, "z": self.z, "yaw": self.yaw},
            "velocity": [self.vel[0], self.vel[1], 0.0],
            "acceleration": [acc[0], acc[1], 0.0],
            "angular_velocity": [0.0, 0.0, (self.yaw - yaw_before) / self.step_s],
            "steer_angle": math.degrees(self.delta),
            "collisions": collisions,
        }

    def close(self):
        pass


class CarlaWorld:
    """The real server through CARLA's Python client."""

    def __init__(self, setup):
        try:
            import carla  # noqa: PLC0415 (only the real mode needs the client)
        except ImportError as e:
            raise BridgeError("no_client", f"cannot import CARLA's Python client ({e}); run tools/setup.sh "
                              "or pip install carla==0.9.16 into the Python carla-gs uses (CARLA_GS_PYTHON)")
        self.carla = carla
        host, port, timeout = setup["host"], int(setup["port"]), float(setup["timeout_s"])
        self.client = carla.Client(host, port)
        self.client.set_timeout(timeout)
        try:
            self.version = self.client.get_server_version()
        except RuntimeError as e:
            raise BridgeError("no_server", str(e))
        log(f"server {self.version} at {host}:{port}, client {self.client.get_client_version()}")
        self.client.set_timeout(max(timeout, float(setup.get("load_timeout_s", 120.0))))
        params = carla.OpendriveGenerationParameters(
            vertex_distance=1.0, max_road_length=50.0, wall_height=0.0, additional_width=0.6,
            smooth_junctions=True, enable_mesh_visibility=True, enable_pedestrian_navigation=False)
        self.world = self.client.generate_opendrive_world(setup["xodr"], params)
        self.client.set_timeout(timeout)
        self.original_settings = self.world.get_settings()
        settings = self.world.get_settings()
        settings.synchronous_mode = True
        settings.fixed_delta_seconds = float(setup["step_s"])
        settings.substepping = True
        settings.max_substep_delta_time = SUBSTEP_S
        settings.max_substeps = MAX_SUBSTEPS
        self.world.apply_settings(settings)
        self.step_s = float(setup["step_s"])
        self.lib = self.world.get_blueprint_library()
        self.actors = {}
        self.specs = {a["id"]: a for a in setup["actors"]}
        self.spawned = []
        self.lock = threading.Lock()
        self.events = []
        adv = setup["adversary"]
        self.adversary = self._spawn(adv.get("blueprint") or BLUEPRINTS["vehicle"], adv["transform"], 0, "adversary")
        yaw = math.radians(adv["transform"]["yaw"])
        v = float(adv["speed_mps"])
        self.adversary.set_target_velocity(carla.Vector3D(v * math.cos(yaw), v * math.sin(yaw), 0.0))
        sensor_bp = self.lib.find("sensor.other.collision")
        self.sensor = self.world.spawn_actor(sensor_bp, carla.Transform(), attach_to=self.adversary)
        self.spawned.append(self.sensor)
        self.sensor.listen(self._on_collision)
        self.frame = self.world.get_snapshot().frame

    def _transform(self, t, lift=0.0):
        c = self.carla
        return c.Transform(c.Location(x=t["x"], y=t["y"], z=t["z"] + lift), c.Rotation(pitch=0.0, yaw=t["yaw"], roll=0.0))

    def _spawn(self, blueprint, t, k, role):
        bp = self.lib.find(blueprint)
        if bp.has_attribute("role_name"):
            bp.set_attribute("role_name", role)
        actor = self.world.spawn_actor(bp, self._transform(t, SPAWN_LIFT_M + 10.0 * k))
        self.spawned.append(actor)
        actor.set_transform(self._transform(t, 0.05))
        return actor

    def _on_collision(self, event):
        other = event.other_actor
        name = self.ids_by_actor.get(other.id, f"carla:{other.type_id}") if other is not None else "unknown"
        with self.lock:
            self.events.append({"frame": event.frame, "other": name,
                                "other_type": other.type_id if other is not None else ""})

    @property
    def ids_by_actor(self):
        return {a.id: i for i, a in self.actors.items()}

    def ready(self):
        return {"type": "ready", "protocol": PROTOCOL, "server_version": self.version,
                "map": self.world.get_map().name, "frame": self.frame}

    def step(self, msg):
        c = msg["control"]
        self.adversary.apply_control(self.carla.VehicleControl(
            throttle=float(c["throttle"]), steer=float(c["steer"]), brake=float(c["brake"])))
        present = set()
        for k, a in enumerate(msg["actors"]):
            present.add(a["id"])
            actor = self.actors.get(a["id"])
            if actor is None:
                spec = self.specs.get(a["id"], {"class": "other"})
                actor = self._spawn(BLUEPRINTS.get(spec["class"], BLUEPRINTS["other"]), a["transform"], k + 1, "replayed")
                actor.set_simulate_physics(False)
                self.actors[a["id"]] = actor
            else:
                actor.set_transform(self._transform(a["transform"]))
        for gone in [i for i in self.actors if i not in present]:
            actor = self.actors.pop(gone)
            self.spawned.remove(actor)
            actor.destroy()
        self.frame = self.world.tick()
        t = self.adversary.get_transform()
        v, acc, w = self.adversary.get_velocity(), self.adversary.get_acceleration(), self.adversary.get_angular_velocity()
        steer = self.adversary.get_wheel_steer_angle(self.carla.VehicleWheelLocation.FL_Wheel)
        with self.lock:
            events, self.events = self.events, []
        return {
            "type": "state",
            "frame": self.frame,
            "transform": {"x": t.location.x, "y": t.location.y, "z": t.location.z, "yaw": t.rotation.yaw},
            "velocity": [v.x, v.y, v.z],
            "acceleration": [acc.x, acc.y, acc.z],
            "angular_velocity": [w.x, w.y, w.z],
            "steer_angle": steer,
            "collisions": events,
        }

    def close(self):
        try:
            if getattr(self, "sensor", None) is not None and self.sensor.is_listening:
                self.sensor.stop()
            for actor in reversed(self.spawned):
                actor.destroy()
            self.spawned = []
        finally:
            # Never leave the server frozen in synchronous mode.
            self.world.apply_settings(self.original_settings)


def main(argv):
    fake = "--fake" in argv
    world = None
    try:
        for line in sys.stdin:
            if not line.strip():
                continue
            try:
                msg = json.loads(line)
            except ValueError as e:
                error("protocol", f"not a JSON line: {e}")
                return 2
            kind = msg.get("type")
            if kind == "setup":
                if msg.get("protocol") != PROTOCOL:
                    error("protocol", f"protocol {msg.get('protocol')} requested, this bridge speaks {PROTOCOL}")
                    return 2
                step_s = float(msg["step_s"])
                if not 0.0 < step_s <= SUBSTEP_S * MAX_SUBSTEPS:
                    error("setup", f"step_s must be in (0, {SUBSTEP_S * MAX_SUBSTEPS}] s, got {step_s}")
                    return 2
                world = FakeWorld(msg) if fake else CarlaWorld(msg)
                send(world.ready())
            elif kind == "step":
                if world is None:
                    error("protocol", "step before setup")
                    return 2
                send(world.step(msg))
            elif kind == "close":
                if world is not None:
                    world.close()
                    world = None
                send({"type": "closed"})
                return 0
            else:
                error("protocol", f"unknown message type {kind!r}")
                return 2
    except BridgeError as e:
        error(e.kind, str(e))
        return 3
    except Exception as e:  # noqa: BLE001 (report anything to carla-gs rather than die silently)
        error("bridge", f"{type(e).__name__}: {e}")
        return 4
    finally:
        if world is not None:
            try:
                world.close()
            except Exception as e:  # noqa: BLE001
                log(f"cleanup failed: {e}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
