"""GetDP decks and the Python runner that drives the ``getdp`` executable (GetDP 3.2.0).

Layout
------
``decks/Lib_PulsedForming.pro``  template library (DefineConstant/DefineGroup/DefineFunction):
    2D planar (a_z) or axisymmetric (r a_phi, VolAxiSqu, a = 0 on the axis) transient eddy
    currents, implicit Euler, stranded coils (prescribed damped sine / table, or in series
    with a capacitor bank C, V0, R_ext, L_ext through GetDP circuit equations), massive
    conductors, optional shell transformation (VolAxiSquSphShell / VolSphShell), per-sub-step
    tables of f = j x B and Joule power per conductor element, coil I/U/P/F, conductor F/P,
    magnetic energy, capacitor voltage.
``decks/em_case.pro``  generic case deck: maps physical ids (see :mod:`.mesh`) to the groups.
``mesh.py``     :class:`EMMesh` (points, triangles, tags), :func:`write_msh22`, builders
                :func:`coil_conductor_mesh` (gmsh) and :func:`slab_mesh`.
``runner.py``   :func:`run_getdp` (argv, cwd=run_dir, one log, return code, log scan),
                :class:`GetDPError`, :data:`FAST_MPI_ENV`.
``model.py``    :class:`EMModel` (+ :class:`Coil`, :class:`Conductor`, :class:`Circuit`,
                :class:`DampedSine`, :class:`CurrentTable`), :class:`EMState`,
                :class:`EMStepResult`.
``solver.py``   :class:`GetDPSolver` (one EM step = one getdp run).
``metrics.py``  :func:`em_metrics` -> ``coil_current_peak_kA``, ``force_impulse_Ns``,
                ``coil_joule_heat_J``, ``coil_temperature_rise_K``.

Stepping API (staggered coupling)
---------------------------------
::

    solver = GetDPSolver(model, work_dir, executable="getdp", petsc_args=DEFAULT_PETSC_ARGS,
                         timeout=None, keep_runs=None, reuse_pre=True,   # one sub-folder per run
                         time_scheme="euler")   # or "bdf2": second order, n_sub = 1 (see .bdf2)
    state = solver.initial_state(t0=0.0)             # EMState, JSON-able (to_dict / save / load)
    for k in range(n_em_steps):
        mesh_k = mesh0.with_points(current_positions)   # same connectivity, moved nodes
        result, state = solver.step(mesh_k, state, t_end=t_k + dt_em, n_sub=1,
                                    material_points=reference_positions,  # optional, see below
                                    run_name=None, force_init_path=False, element_output="all",
                                    field_output=False)
        result.elements             # rows of mesh_k.triangles in the massive conductors
        result.force_density        # (n_sub, n_el, 2) N/m^3 = j x B at element centroids
        result.force_density_mean   # (n_el, 2) impulse-consistent mean over the sub-steps
        result.joule_density        # (n_sub, n_el) W/m^3
        result.conductor_force      # (n_sub, n_conductors, 2) N (2 pi included in axisymmetry)
        result.coil_current, result.coil_voltage, result.capacitor_voltage, result.coil_heat,
        result.coil_temperature_rise, result.magnetic_energy
        result.b_cells, result.a_nodes   # field_output=True: B on every triangle, nodal potential
    solver.post_fields(result, mesh_k)   # the same afterwards from the step's em.res (getdp -pos)

Same connectivity as the previous step: the field continues with ``-restart -res <prev .res>``
(and ``getdp -cal`` with the previous ``.pre``); with ``material_points`` given, only if the
coil/conductor nodes are the same material points as before (Lagrangian nodes).
A new mesh (different connectivity) or ``force_init_path=True``: the previous nodal unknown
(r a_phi) of coils and conductors is interpolated in *material* coordinates (pass
``material_points``, the reference position of every new node; default ``mesh.points``) and
fed through an ``Init`` constraint.  The circuit state (capacitor voltage, current) is carried
in :class:`EMState` and enters through ``Init`` constraints.  Both paths reproduce a continuous
run to round-off on a fixed mesh (tests/getdp/test_stepping.py).

Failures raise :class:`GetDPError` (message ends with the log tail; the run folder stays);
getdp warnings become ``RuntimeWarning``.  ``element_output="last"``/``"none"`` skips the
per-element tables on long runs; ``field_output=True`` adds the whole-domain tables of
PostOperation ``EM_Field`` (ask for them only on the steps whose fields are written).

Conventions: GetDP frame (x, y) = (r, z) in axisymmetry; a positive coil current flows along
+z of that frame (-e_phi); forces are unaffected.  Coil voltage is the drop in the current's
direction (receptor convention).  Massive conductors carry only induced current (no electric
scalar potential): exact for closed rings in axisymmetry; in planar they are shorted at infinity.
"""
from .applied_field import AppliedField
from .mesh import EMMesh, Rect, coil_conductor_mesh, coil_tag, conductor_tag, slab_mesh, write_msh22
from .metrics import em_metrics
from .runner import FAST_MPI_ENV, GetDPError, RunInfo, find_getdp, run_getdp
from .solver import (DEFAULT_PETSC_ARGS, Circuit, Coil, Conductor, CurrentTable, DampedSine, EMModel, EMState,
                     EMStepResult, GetDPSolver)

__all__ = [
    "EMMesh", "Rect", "coil_conductor_mesh", "coil_tag", "conductor_tag", "slab_mesh", "write_msh22",
    "em_metrics", "FAST_MPI_ENV", "GetDPError", "RunInfo", "find_getdp", "run_getdp", "Circuit", "Coil",
    "Conductor", "CurrentTable", "DampedSine", "EMModel", "EMState", "EMStepResult", "GetDPSolver",
    "DEFAULT_PETSC_ARGS", "AppliedField",
]
