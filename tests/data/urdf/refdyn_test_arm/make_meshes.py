#!/usr/bin/env python3
"""Writes the small visual meshes of the test robots (meshes/*.stl, *.dae, *.obj), in the shape
real robot descriptions have them: one file per link, in the link frame, a joint housing (a
cylinder along the link's z axis at its origin) and a tube from the origin to the next joint
(the bases: a pedestal). COLLADA files without normals (viewers compute them).
Deterministic: running it again writes the same bytes. Usage: make_meshes.py [OUTDIR]."""
import math
import os
import struct
import sys

OUT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "meshes")
SEG = 16  # facets around a cylinder


def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a):
    n = math.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else (0.0, 0.0, 1.0)


def cylinder(p0, p1, r):
    """Triangles (counter-clockwise seen from outside) of a closed cylinder from p0 to p1."""
    ax = norm(sub(p1, p0))
    helper = (1.0, 0.0, 0.0) if abs(ax[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = norm(cross(ax, helper))
    v = cross(ax, u)
    ring = lambda p, k: tuple(p[i] + r * (math.cos(2 * math.pi * k / SEG) * u[i] + math.sin(2 * math.pi * k / SEG) * v[i])
                              for i in range(3))
    tris = []
    for k in range(SEG):
        a0, a1, b0, b1 = ring(p0, k), ring(p0, k + 1), ring(p1, k), ring(p1, k + 1)
        tris += [(a0, a1, b1), (a0, b1, b0), (p0, a1, a0), (p1, b0, b1)]
    return tris


def link_shape(r, to):
    """A joint housing of radius r (length 2r along z) and a tube of radius 0.7 r to `to`."""
    tris = cylinder((0.0, 0.0, -r), (0.0, 0.0, r), r)
    if math.sqrt(sum(c * c for c in to)) > 1e-9:
        tris += cylinder((0.0, 0.0, 0.0), to, 0.7 * r)
    return tris


def normal(t): return norm(cross(sub(t[1], t[0]), sub(t[2], t[0])))


def write_stl(name, tris):
    with open(os.path.join(OUT, name), "wb") as f:
        f.write(b"refdyn test mesh".ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for t in tris:
            f.write(struct.pack("<3f", *normal(t)))
            for p in t:
                f.write(struct.pack("<3f", *p))
            f.write(struct.pack("<H", 0))


def vertices(tris):
    index, verts, faces = {}, [], []
    for t in tris:
        face = []
        for p in t:
            key = tuple(round(c, 6) for c in p)
            if key not in index:
                index[key] = len(verts)
                verts.append(key)
            face.append(index[key])
        faces.append(face)
    return verts, faces


def write_obj(name, tris):
    verts, faces = vertices(tris)
    with open(os.path.join(OUT, name), "w") as f:
        f.write("# refdyn test mesh\no %s\n" % os.path.splitext(name)[0])
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % v)
        for fc in faces:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in fc))


def write_dae(name, tris, rgb):
    verts, faces = vertices(tris)
    pos = " ".join("%.6f %.6f %.6f" % v for v in verts)
    idx = " ".join("%d %d %d" % tuple(fc) for fc in faces)
    color = "%.3f %.3f %.3f 1" % rgb
    with open(os.path.join(OUT, name), "w") as f:
        f.write("""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_effects>
    <effect id="paint-effect"><profile_COMMON><technique sid="common"><phong>
      <diffuse><color sid="diffuse">%s</color></diffuse>
    </phong></technique></profile_COMMON></effect>
  </library_effects>
  <library_materials><material id="paint" name="paint"><instance_effect url="#paint-effect"/></material></library_materials>
  <library_geometries>
    <geometry id="shape" name="shape"><mesh>
      <source id="shape-positions"><float_array id="shape-positions-array" count="%d">%s</float_array>
        <technique_common><accessor source="#shape-positions-array" count="%d" stride="3">
          <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
        </accessor></technique_common></source>
      <vertices id="shape-vertices"><input semantic="POSITION" source="#shape-positions"/></vertices>
      <triangles material="paint" count="%d"><input semantic="VERTEX" source="#shape-vertices" offset="0"/><p>%s</p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene" name="scene"><node id="link" name="link">
      <instance_geometry url="#shape"><bind_material><technique_common>
        <instance_material symbol="paint" target="#paint"/>
      </technique_common></bind_material></instance_geometry>
    </node></visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
""" % (color, 3 * len(verts), pos, len(verts), len(faces), idx))


os.makedirs(OUT, exist_ok=True)
ORANGE, GREY = (0.95, 0.45, 0.05), (0.55, 0.57, 0.6)
# the 7-joint arm (urdf/arm7_hand.urdf): each link to its child joint's origin
write_stl("arm7_base.stl", cylinder((0.0, 0.0, 0.02), (0.0, 0.0, 0.16), 0.1))
write_stl("arm7_link1.stl", link_shape(0.085, (0.0, 0.0, 0.2)))
write_dae("arm7_link2.dae", link_shape(0.085, (0.0, 0.21, 0.0)), ORANGE)
write_stl("arm7_link3.stl", link_shape(0.08, (0.0, 0.0, 0.19)))
write_dae("arm7_link4.dae", link_shape(0.08, (0.0, 0.2, 0.0)), ORANGE)
write_obj("arm7_link5.obj", link_shape(0.07, (0.0, 0.0, 0.21)))
write_obj("arm7_link6.obj", link_shape(0.065, (0.0, 0.085, 0.0)))
write_stl("arm7_link7.stl", link_shape(0.05, (0.0, 0.0, 0.045)))
write_dae("hand.dae", cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 0.06), 0.045) + cylinder((0.0, -0.09, 0.05), (0.0, 0.09, 0.05), 0.02), GREY)
write_stl("finger.stl", cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 0.05), 0.01))
# the 6-joint arm (urdf/arm6.urdf)
write_dae("arm6_base.dae", cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 0.15), 0.08), GREY)
write_dae("arm6_shoulder.dae", link_shape(0.07, (0.0, 0.13, 0.0)), GREY)
write_dae("arm6_upperarm.dae", link_shape(0.065, (0.0, -0.42, 0.0)), GREY)
write_dae("arm6_forearm.dae", link_shape(0.055, (0.0, -0.39, 0.0)), GREY)
write_stl("arm6_wrist1.stl", link_shape(0.045, (0.0, 0.0, 0.1)))
write_stl("arm6_wrist2.stl", link_shape(0.045, (0.0, 0.0, 0.095)))
write_obj("arm6_wrist3.obj", link_shape(0.04, (0.0, 0.0, 0.08)))
