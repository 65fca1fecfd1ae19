#!/usr/bin/env python3
# `python3 docs/random_scenes.py SEED FRAMES MARKERS OUT.json FX FY CX CY`:
# a `render SET.json --poses` scenes file (docs/formats.md, "Render scenes
# file") of random frames, for the figures in docs/commands.md ("Scenes of
# several markers").
import json, math, random, sys
# Random scenes of the set's markers: each frame places 2 to `markers` of them
# at depths 300-1000 mm, anywhere in the image's central region, tilted and
# panned within +-40 deg, at any roll. Seeded.
seed, frames, markers, out = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
fx, fy, cx, cy = float(sys.argv[5]), float(sys.argv[6]), float(sys.argv[7]), float(sys.argv[8])
rng = random.Random(seed)
def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == 'x': return [[1,0,0],[0,c,-s],[0,s,c]]
    if axis == 'y': return [[c,0,s],[0,1,0],[-s,0,c]]
    return [[c,-s,0],[s,c,0],[0,0,1]]
def mul(a, b): return [[sum(a[i][k]*b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
scenes = []
for f in range(frames):
    frame = []
    for m in sorted(rng.sample(range(markers), rng.randint(2, markers))):
        z = rng.uniform(300, 1000)
        u, v = rng.uniform(200, 1080), rng.uniform(150, 570)
        t = [(u - cx) / fx * z, (v - cy) / fy * z, z]
        r = mul(rot('z', rng.uniform(-math.pi, math.pi)), mul(rot('y', math.radians(rng.uniform(-40, 40))), rot('x', math.radians(rng.uniform(-40, 40)))))
        frame.append({"marker": m + 1, "R": r, "t": t})
    scenes.append(frame)
json.dump(scenes, open(out, 'w'))
