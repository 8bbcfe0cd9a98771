"""Meshes for the tests: E3SM's HOMME test meshes, shipped in ``tests/data/meshes`` (its README names
their source and licence), and the project's own, built here: the cube
(``cube_mesh``) and ``icosahedral_mesh``, whose nodes are shared by 3 to 6 elements as on a refined
mesh."""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import numpy as np

from swe_sphere.cases.library import make_case
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.refine import Box, make_mesh, refined_cube
from swe_sphere.mesh.mesh import Mesh, check
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import make_stepper

import roundoff

MESHES = Path(__file__).resolve().parent / "data" / "meshes"
TEMPEST_NE2 = MESHES / "TEMPEST_NE2.g"  # the uniform ne2 cube, made by TempestRemap
MOUNTAIN = MESHES / "mountain_10_x2.g"  # ne10 refined 2x over TC5's mountain (CUBIT paving)
TC2_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]
TC6_TERMS = [*TC2_TERMS, "hyperviscosity"]


def case_model(grid, case_name: str, terms: list, **options):
    """(case, its ShallowWater on ``grid`` on the CPU with the case's fcor, hs and g; ``options``
    the model's others: nu, threads, per_element...)."""
    case = make_case(case_name)
    return case, ShallowWater.from_case(grid, case, terms, device="cpu", **options)


def equiangular(mesh: Mesh) -> Mesh:
    """``mesh`` through the equiangular map in each element's cube face (``face_map``)."""
    return dataclasses.replace(mesh, map="equiangular")


MOUNTAIN_BOX4 = Box(15.0, 45.0, 255.0, 285.0)  # 2×2 elements of the ne4 cube about TC5's mountain


@functools.cache
def refined_ne4() -> Mesh:
    """The ne4 cube refined 2× over ``MOUNTAIN_BOX4`` (124 elements; two levels, 66 and 58, at np 4),
    made once a process and read-only: ``refine.smooth``'s sweeps took 0.7 s (0.2 s since they build no
    ``CubedSphere``), and the grid, level, local-time-stepping, gradient and MPI tests each used to
    make it again."""
    mesh = refined_cube(4, MOUNTAIN_BOX4, 1)
    mesh.coords.flags.writeable = mesh.quads.flags.writeable = False
    return mesh


@functools.cache
def refined_ne4_grid() -> CubedSphere:
    """``refined_ne4``'s CubedSphere at np 4, one a process (treat as read-only)."""
    return CubedSphere(0, 4, mesh=refined_ne4())


def refined_equiangular() -> Mesh:
    """The ne4 cube refined 2x over a box, unsmoothed (every node on the turned cube's
    equiangular lattice), through the equiangular map: 124 elements, valences 3 to 5."""
    return equiangular(make_mesh(4, box=Box(20.0, 40.0, 260.0, 280.0), levels=1, smoothing=0))


def run_steps(grid, case_name: str, terms: list, steps: int, dt: float, **options):
    """(the state (u, v, h) (3, N) after ``steps`` SSP-RK3 steps of ``dt`` s of ``case_name`` on
    ``grid``, its start (3, N)); ``options`` the model's (``case_model``)."""
    case, model = case_model(grid, case_name, terms, **options)
    stepper = make_stepper("ssprk3", model, dt)
    start = np.stack(case.initial(grid.lat, grid.lon))
    x = model.new_state(*start)
    for _ in range(steps):
        stepper.step(x)
    return x.numpy(), start


def tc2_l2_by_np(mesh: Mesh, nps, ne: int = 0, steps: int = 12, dt: float = 60.0) -> list[float]:
    """TC2 (steady, exact; no ∇⁴) for ``steps`` SSP-RK3 steps of ``dt`` s on ``mesh`` at each
    np of ``nps`` (``ne``: 0 for a mesh, the cube's for a moved cube, as ``CubedSphere``): the
    normalized l2 error of h of each run, whose mass change is checked to be round-off
    (``roundoff.mass_change_bound`` of its RHS evaluations)."""
    errors = []
    for np_ in nps:
        g = CubedSphere(ne, np_, mesh=mesh)
        x, start = run_steps(g, "tc2_steady", TC2_TERMS, steps, dt)
        h, h0 = x[2], start[2]
        roundoff.within(
            abs(g.integrate(h) / g.integrate(h0) - 1), roundoff.mass_change_bound(3 * steps, g.nnodes), "|mass change|"
        )
        errors.append(math.sqrt(g.integrate((h - h0) ** 2) / g.integrate(h0**2)))
    return errors


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """The regular icosahedron's 12 unit vertices and 20 faces, counter-clockwise from outside."""
    t = (1 + 5**0.5) / 2
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t]]
        + [[t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
        dtype=float,
    )
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2]]
        + [[10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5]]
        + [[2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    )
    return v / np.linalg.norm(v, axis=1)[:, None], f


def _midpoints(coords: list, faces: np.ndarray) -> tuple[np.ndarray, list]:
    """(F, 3) the node of each face edge's midpoint (k: from corner k to k+1), added to ``coords``."""
    index: dict = {}
    mids = np.empty(faces.shape, dtype=np.int64)
    for n, face in enumerate(faces):
        for k in range(3):
            key = tuple(sorted((face[k], face[(k + 1) % 3])))
            if key not in index:
                m = coords[key[0]] + coords[key[1]]
                index[key] = len(coords)
                coords.append(m / np.linalg.norm(m))
            mids[n, k] = index[key]
    return mids, coords


def quadrilaterals(coords: list, faces: np.ndarray, name: str) -> Mesh:
    """The checked mesh of a triangulation (unit ``coords``, ``faces`` counter-clockwise from
    outside) with each triangle split into 3 quadrilaterals through its centre and edge
    midpoints: a node of k triangles is one of k quadrilaterals, edge midpoints of 4, centres of 3."""
    m, coords = _midpoints(list(coords), faces)
    centres = np.array(coords)[faces].sum(axis=1)
    centre = len(coords) + np.arange(len(faces))
    coords = np.vstack([coords, centres / np.linalg.norm(centres, axis=1)[:, None]])
    a, b, c = faces.T
    corners = ((a, m[:, 0], centre, m[:, 2]), (b, m[:, 1], centre, m[:, 0]), (c, m[:, 2], centre, m[:, 1]))
    return check(Mesh(coords, np.concatenate([np.stack(x, axis=1) for x in corners]), name))


def icosahedral_mesh(subdivisions: int = 1) -> Mesh:
    """The icosahedron's triangles, each split into 4 ``subdivisions`` times (new nodes on the
    sphere), as ``quadrilaterals``: nodes shared by 3 (triangle centres), 4 (edge midpoints),
    5 (the icosahedron's vertices) and 6 elements (the subdivisions' vertices). 60·4^s elements."""
    v, faces = _icosahedron()
    coords = list(v)
    for _ in range(subdivisions):
        m, coords = _midpoints(coords, faces)
        a, b, c = faces.T
        faces = np.concatenate(
            [np.stack(x, axis=1) for x in ((a, m[:, 0], m[:, 2]), (b, m[:, 1], m[:, 0]), (c, m[:, 2], m[:, 1]), m.T)]
        )
    return quadrilaterals(coords, faces, f"icosahedral quads ({subdivisions} subdivisions)")


def bipyramid_mesh(n: int) -> Mesh:
    """The n-gonal bipyramid's 2n triangles (the poles and n points on the equator) as
    ``quadrilaterals``: both poles are nodes of n elements (``check`` refuses n > 7)."""
    lon = 2 * np.pi * np.arange(n) / n
    coords = [np.array([0.0, 0, 1]), np.array([0.0, 0, -1]), *np.stack([np.cos(lon), np.sin(lon), 0 * lon], axis=1)]
    k = np.arange(n)
    ring, nxt = 2 + k, 2 + (k + 1) % n
    faces = np.concatenate(
        [np.stack([np.zeros(n, int), ring, nxt], axis=1), np.stack([np.ones(n, int), nxt, ring], axis=1)]
    )
    return quadrilaterals(coords, faces, f"{n}-gonal bipyramid quads")
