"""Embedding crowdweave in your own game loop.

The game owns the window, the input and the clock; crowdweave is a library it steps::

    world = World("default")                  # motion library (built by `crowdweave demo`)
    world.spawn("guard", (0, 0))
    world.go_to("guard", (5, 3), heading=1.57)
    while running:
        dt = clock.tick()                     # real seconds since the last frame
        world.step(dt)                        # fixed 1/30 s ticks inside, planning time-sliced
        joints = world.poses()                # (characters, joints, 3), interpolated
        draw(joints)

This sample draws the characters as stick figures seen from above in a pyglet window; click
anywhere to send the nearest character there. ``--headless`` runs the same loop with no
window (for tests and servers): ``python samples/embed_game.py --headless --ticks 300``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from runtime.world import World


def make_world(n: int = 8, seed: int = 0, budget_ms: float = 4.0) -> World:
    world = World("default", seed=seed, budget_ms=budget_ms)
    rng = np.random.default_rng(seed)
    for i in range(n):
        a = 2 * math.pi * i / n
        world.spawn(f"npc{i}", (4 * math.sin(a), 4 * math.cos(a)), heading=a + math.pi)
    # everybody crosses the plaza to the opposite side
    for i in range(n):
        a = 2 * math.pi * i / n + math.pi + rng.uniform(-0.3, 0.3)
        world.go_to(f"npc{i}", (4 * math.sin(a), 4 * math.cos(a)))
    return world


def run_headless(ticks: int, n: int, budget_ms: float = 4.0) -> dict:
    world = make_world(n, budget_ms=budget_ms)
    events = []
    world.on("*", events.append)
    t = time.perf_counter()
    for _ in range(ticks):
        world.step(world.dt)             # the game's clock would pass real time here
        joints = world.poses()           # what a renderer would draw this frame
    wall = time.perf_counter() - t
    return {"ticks": world.stats["ticks"], "characters": len(world.names), "joints_shape": joints.shape,
            "events": [(e.kind, e.character) for e in events], "seconds": wall}


def run_window(n: int) -> None:
    import pyglet
    from pyglet import gl

    world = make_world(n)
    win = pyglet.window.Window(960, 720, "crowdweave embedded in a game loop", resizable=True)
    parents = world.graph.skeleton.parents
    bones = np.flatnonzero(parents >= 0)
    scale, centre = 45.0, np.array([480.0, 360.0])
    batch = pyglet.graphics.Batch()
    program = pyglet.graphics.get_default_shader()
    vlist = None

    def to_screen(xz):
        return centre + scale * np.stack([xz[..., 0], xz[..., 1]], axis=-1)

    @win.event
    def on_draw():
        nonlocal vlist
        win.clear()
        joints = world.poses()                               # (N, J, 3)
        a = to_screen(joints[:, parents[bones]][..., [0, 2]])
        b = to_screen(joints[:, bones][..., [0, 2]])
        seg = np.stack([a, b], axis=2).reshape(-1, 2)        # line list, top view
        pos = np.concatenate([seg, np.zeros((len(seg), 1))], axis=1).astype(np.float32).ravel()
        if vlist is None or vlist.count != len(seg):
            if vlist is not None:
                vlist.delete()
            vlist = program.vertex_list(len(seg), gl.GL_LINES, batch=batch,
                                        position=("f", pos), colors=("Bn", [230, 200, 120, 255] * len(seg)))
        else:
            vlist.position[:] = pos
        batch.draw()

    @win.event
    def on_mouse_press(x, y, button, modifiers):
        xz = (np.array([x, y]) - centre) / scale
        roots = world.root_states()
        if len(roots):
            i = int(np.argmin(np.hypot(roots[:, 0] - xz[0], roots[:, 1] - xz[1])))
            world.go_to(world.names[i], xz)

    pyglet.clock.schedule_interval(lambda dt: world.step(dt), 1 / 60)
    pyglet.app.run()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--headless", action="store_true", help="no window: run the loop for --ticks ticks")
    p.add_argument("--ticks", type=int, default=300)
    p.add_argument("--characters", type=int, default=8)
    a = p.parse_args(argv)
    if a.headless:
        r = run_headless(a.ticks, a.characters)
        print(f"{r['ticks']} ticks, {r['characters']} characters, poses {r['joints_shape']}, "
              f"{len(r['events'])} events, {r['seconds']:.2f} s")
        return 0
    run_window(a.characters)
    return 0


if __name__ == "__main__":
    sys.exit(main())
