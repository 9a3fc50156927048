"""The cells' temperatures reach GetDP's elements (issue 33, item 3): :func:`element_temperatures` gives every EM
element of a heated body the temperature of the mechanical cell on the same nodes, whatever the order of cells,
elements and nodes (a body cut from the EM mesh), and leaves out bodies without a temperature."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pulseform.orchestrator.em.joule_heat import element_temperatures


def test_each_element_gets_its_cells_temperature():
    rng = np.random.default_rng(3)
    em_tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [5, 6, 7], [6, 8, 7]])
    tags = np.array([201, 201, 201, 201, 1, 202])
    body_to_em = np.array([4, 3, 2, 1, 0])              # body node row -> EM node
    em_to_body = np.argsort(body_to_em)
    order = rng.permutation(4)
    cells = em_to_body[em_tri[:4][order]][:, [1, 2, 0]]  # the same triangles, other order, rotated nodes
    temps = np.array([300.0, 310.0, 320.0, 330.0])
    mech = SimpleNamespace(heated_cells=lambda: {"sheet": cells}, cell_temperatures=lambda: {"sheet": temps})
    bodies = [SimpleNamespace(name="sheet", tag=201, body_to_em=body_to_em),
              SimpleNamespace(name="die", tag=202, body_to_em=np.array([6, 8, 7]))]   # no temperature
    rows, values = element_temperatures(mech, bodies, em_tri, tags)
    assert sorted(rows.tolist()) == [0, 1, 2, 3]
    got = dict(zip(rows.tolist(), values.tolist()))
    for cell, element in enumerate(order):
        assert got[int(element)] == temps[cell]


def test_each_tetrahedron_gets_its_cells_temperature():
    """The same hand-over in 3D (the 3D participant passes its tetrahedra and their physical ids): a cube of five
    tetrahedra in a body whose node rows are the EM nodes reversed, the cells in another order, nodes rotated."""
    rng = np.random.default_rng(5)
    em_tet = np.array([[0, 1, 3, 4], [1, 2, 3, 6], [1, 4, 5, 6], [3, 4, 6, 7], [1, 3, 4, 6], [8, 9, 10, 11]])
    tags = np.array([201, 201, 201, 201, 201, 1])
    body_to_em = np.arange(8)[::-1].copy()
    em_to_body = np.argsort(body_to_em)
    order = rng.permutation(5)
    cells = em_to_body[em_tet[:5][order]][:, [2, 3, 0, 1]]
    temps = 300.0 + 7.0 * np.arange(5)
    mech = SimpleNamespace(heated_cells=lambda: {"sheet": cells}, cell_temperatures=lambda: {"sheet": temps})
    rows, values = element_temperatures(mech, [SimpleNamespace(name="sheet", tag=201, body_to_em=body_to_em)],
                                        em_tet, tags)
    assert sorted(rows.tolist()) == [0, 1, 2, 3, 4]
    got = dict(zip(rows.tolist(), values.tolist()))
    for cell, element in enumerate(order):
        assert got[int(element)] == temps[cell]
