"""Bad case files and overrides: exit code 2, one line naming file and key, never a traceback.

The base is the shipped bar-impact case; each entry mutates one thing.
"""

from __future__ import annotations

import copy
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.case.model import Case
from pulseform.orchestrator.cli import main
from pulseform.orchestrator.case.schema import PLAUSIBLE, reference_rows

REPO = Path(__file__).resolve().parents[2]
BASE = tomllib.loads((REPO / "cases/bar_impact/case.toml").read_text())
FLOW_TABLE = {"type": "table", "plastic_strain": [0.0, 0.1, 0.2], "yield_stress": [2e8, 2.5e8, 3e8]}
FLOW_JC = {"type": "johnson_cook", "A": 3.24e8, "B": 1.14e8, "n": 0.42, "C": 0.002, "m": 1.34,
           "melting_temperature": 855.0}
COND_TABLE = {"type": "table", "temperatures": [293.0, 500.0, 800.0], "conductivities": [3.5e7, 2.2e7, 1.5e7]}
PULSE = {"type": "pulse_sin2", "body": "left", "surface": {"xmin": 0.0, "xmax": 0.0},
         "amplitude": 30e6, "beta": 1e4, "omega": 1e5, "t_end": 3e-4}


def _set(d, path, value):
    *head, last = path
    for k in head:
        d = d[k]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()

# (id, [(path, value), ...], text that must appear in the message)
BAD_FILES = [
    ("negative_end", [(("time", "end"), -1.0)], "time.end"),
    ("zero_end", [(("time", "end"), 0.0)], "time.end"),
    ("cfl_above_one", [(("time", "cfl"), 1.5)], "time.cfl"),
    ("cfl_string", [(("time", "cfl"), "fast")], "time.cfl"),
    ("dt_max_zero", [(("time", "dt_max"), 0.0)], "time.dt_max"),
    ("n_zero", [(("coupling",), {"n": 0})], "coupling.n"),
    ("n_float", [(("coupling",), {"n": 2.5})], "coupling.n"),
    ("h0_zero", [(("contact", 0, "h0"), 0.0)], "contact[0].h0"),
    ("stiffness_negative", [(("contact", 0, "stiffness"), -1e8)], "contact[0].stiffness"),
    ("master_unknown", [(("contact", 0, "master"), "nobody")], "contact[0].master"),
    ("master_is_slave", [(("contact", 0, "master"), "left")], "contact[0].master"),
    ("mesh_size_negative", [(("bodies", 0, "mesh_size"), -0.1)], "bodies[0].mesh_size"),
    ("material_undefined", [(("bodies", 0, "material"), "steel")], "bodies[0].material"),
    ("negative_thickness", [(("bodies", 0, "shape", "height"), -2.0)], "bodies[0].shape.height"),
    ("mechanics_thickness", [(("mechanics", "thickness"), -1e-3)], "mechanics.thickness"),
    ("shape_unknown", [(("bodies", 0, "shape", "type"), "circle")], "bodies[0].shape.type"),
    ("velocity_three", [(("bodies", 0, "initial_velocity"), [1.0, 2.0, 3.0])], "bodies[0].initial_velocity"),
    ("duplicate_body", [(("bodies", 1, "name"), "left")], "bodies[1].name"),
    ("density_zero", [(("materials", "paper_al", "density"), 0.0)], "materials.paper_al.density"),
    ("shear_missing", [(("materials", "paper_al", "shear_modulus"), _DELETE)], "materials.paper_al.shear_modulus"),
    ("unknown_top", [(("tim",), {"end": 1.0})], "tim"),
    ("unknown_nested", [(("time", "ends"), 1.0)], "time.ends"),
    ("formulation_3d", [(("mechanics", "formulation"), "3d")], "mechanics.formulation"),
    ("bool_as_string", [(("mechanics", "bulk_viscosity"), "yes")], "mechanics.bulk_viscosity"),
    ("pulse_no_end", [(("loads",), [{k: v for k, v in PULSE.items() if k != "t_end"}])], "loads[0].t_end"),
    ("pulse_end_before_start", [(("loads",), [dict(PULSE, t_start=1e-3, t_end=5e-4)])], "loads[0].t_end"),
    ("pulse_no_type", [(("loads",), [{k: v for k, v in PULSE.items() if k != "type"}])], "loads[0].type"),
    ("pulse_body_unknown", [(("loads",), [dict(PULSE, body="blank")])], "loads[0].body"),
    ("pulse_omega_zero", [(("loads",), [dict(PULSE, omega=0.0)])], "loads[0].omega"),
    ("no_case_table", [(("case",), _DELETE)], "case"),
    ("empty_name", [(("case", "name"), "  ")], "case.name"),
    ("kind_unknown", [(("case", "kind"), "thermal")], "case.kind"),
    ("wall_zero_normal", [(("walls",), [{"point": [4.0, 0.0], "normal": [0.0, 0.0]}])], "walls[0].normal"),
    ("wall_body_unknown", [(("walls",), [{"point": [4.0, 0.0], "normal": [-1.0, 0.0], "bodies": ["x"]}])],
     "walls[0].bodies[0]"),
    ("probe_quantity", [(("probes", 0, "quantity"), "temperature")], "probes[0].quantity"),
    ("field_interval_too_long", [(("output", "field_interval"), 1.0)], "output.field_interval"),
    ("no_bodies", [(("bodies",), [])], "bodies"),
    ("polygon_clockwise", [(("bodies", 0, "shape"), {"type": "polygon", "points": [[0, 0], [0, 1], [1, 0]]})],
     "bodies[0].shape.points"),
    ("fixed_component_2", [(("bodies", 0, "fixed"), [{"where": {"xmax": 0.0}, "components": [2]}])],
     "bodies[0].fixed[0].components[0]"),
    ("rate_law_unknown", [(("materials", "paper_al", "rate_law"), {"type": "zerilli"})],
     "materials.paper_al.rate_law.type"),
    ("infinite_end", [(("time", "end"), float("inf"))], "time.end"),
    # issue 33, item 5: forming limit curves (minor strictly increasing, major positive, one major per minor, ...)
    ("flc_minor_not_increasing", [(("materials", "paper_al", "forming_limit"),
                                   {"minor_strain": [-0.2, 0.1, 0.0], "major_strain": [0.35, 0.3, 0.22]})],
     "materials.paper_al.forming_limit.minor_strain[2]"),
    ("flc_minor_repeated", [(("materials", "paper_al", "forming_limit"),
                             {"minor_strain": [0.0, 0.0], "major_strain": [0.22, 0.3]})],
     "materials.paper_al.forming_limit.minor_strain[1]"),
    ("flc_major_negative", [(("materials", "paper_al", "forming_limit"),
                             {"minor_strain": [-0.2, 0.0], "major_strain": [0.35, -0.22]})],
     "materials.paper_al.forming_limit.major_strain[1]"),
    ("flc_lengths_differ", [(("materials", "paper_al", "forming_limit"),
                             {"minor_strain": [-0.2, 0.0, 0.2], "major_strain": [0.35, 0.22]})],
     "materials.paper_al.forming_limit.major_strain"),
    ("flc_one_point", [(("materials", "paper_al", "forming_limit"), {"minor_strain": [0.0], "major_strain": [0.22]})],
     "materials.paper_al.forming_limit.minor_strain"),
    ("flc_major_below_minor", [(("materials", "paper_al", "forming_limit"),
                                {"minor_strain": [0.0, 0.4], "major_strain": [0.22, 0.3]})],
     "materials.paper_al.forming_limit.major_strain[1]"),
    ("flc_minor_in_percent", [(("materials", "paper_al", "forming_limit"),
                               {"minor_strain": [-20.0, 0.0], "major_strain": [35.0, 22.0]})],
     "materials.paper_al.forming_limit.minor_strain[0]"),
    ("flc_margin_negative", [(("materials", "paper_al", "forming_limit"),
                              {"minor_strain": [-0.2, 0.0], "major_strain": [0.35, 0.22], "safety_margin": -0.1})],
     "materials.paper_al.forming_limit.safety_margin"),
    ("flc_missing_major", [(("materials", "paper_al", "forming_limit"), {"minor_strain": [-0.2, 0.0]})],
     "materials.paper_al.forming_limit.major_strain"),
    ("axisym_negative_r", [(("mechanics", "formulation"), "axisymmetric"),
                           (("bodies", 0, "shape", "origin"), [-1.0, 0.0])], "bodies[0].shape"),
    # issue 13: the name is a folder name, numbers are finite and plausible, strings hold no NUL
    ("name_absolute_path", [(("case", "name"), "/some/path/VICTIM")], "case.name"),
    ("name_escapes", [(("case", "name"), "../../x")], "case.name"),
    ("name_dot", [(("case", "name"), ".")], "case.name"),
    ("name_dotdot", [(("case", "name"), "..")], "case.name"),
    ("name_too_long", [(("case", "name"), "x" * 101)], "case.name"),
    # issue 32, item 12: a case name may be a name in the user's language ("bar impact", "stoß" are accepted:
    # test_case_names_in_any_language); body names stay ASCII identifiers (--set bodies.<name>.key, columns)
    ("body_name_space", [(("bodies", 0, "name"), "bar impact")], "bodies[0].name"),
    ("body_name_unicode", [(("bodies", 0, "name"), "stoß")], "bodies[0].name"),
    ("name_trailing_space", [(("case", "name"), "Prüfstand ")], "case.name"),
    ("name_leading_space", [(("case", "name"), " Prüfstand")], "case.name"),
    ("name_trailing_dot", [(("case", "name"), "Prüfstand.")], "case.name"),
    ("name_hidden", [(("case", "name"), ".Prüfstand")], "case.name"),
    ("name_leading_hyphen", [(("case", "name"), "-rf")], "case.name"),
    ("name_colon", [(("case", "name"), "Prüfstand: 1")], "case.name"),
    ("name_windows_characters", [(("case", "name"), 'a<b>"c"|d?*')], "case.name"),
    ("name_backslash", [(("case", "name"), "名前\\x")], "case.name"),
    ("name_slash_in_script", [(("case", "name"), "名前/x")], "case.name"),
    ("name_bidi_override", [(("case", "name"), "abc\u202egpj.exe")], "case.name"),
    ("name_zero_width", [(("case", "name"), "Prüf\u200bstand")], "case.name"),
    ("name_no_break_space", [(("case", "name"), "Prüf\u00a0stand")], "case.name"),
    ("name_tab", [(("case", "name"), "Prüf\tstand")], "case.name"),
    ("name_emoji", [(("case", "name"), "Prüfstand \U0001F600")], "case.name"),
    ("name_windows_device", [(("case", "name"), "con")], "case.name"),
    ("name_windows_device_dot", [(("case", "name"), "LPT1.Prüfstand")], "case.name"),
    ("name_cjk_over_100_bytes", [(("case", "name"), "名" * 34)], "case.name"),
    ("name_nul", [(("case", "name"), "bar\x00impact")], "case.name"),
    ("nul_in_description", [(("case", "description"), "a\x00b")], "case.description"),
    ("nul_in_key", [(("case", "a\x00b"), 1)], "case.a\\x00b"),
    ("bulk_modulus_huge", [(("materials", "paper_al", "bulk_modulus"), 1e308)], "materials.paper_al.bulk_modulus"),
    ("density_tiny", [(("materials", "paper_al", "density"), 1e-300)], "materials.paper_al.density"),
    ("height_huge", [(("bodies", 0, "shape", "height"), 1e308)], "bodies[0].shape.height"),
    ("end_huge", [(("time", "end"), 1e30)], "time.end"),
    ("end_nan", [(("time", "end"), float("nan"))], "time.end"),
    ("origin_huge", [(("bodies", 0, "shape", "origin"), [-1e308, 0.0])], "bodies[0].shape.origin[0]"),
    ("velocity_inf", [(("bodies", 0, "initial_velocity"), [float("inf"), 0.0])], "bodies[0].initial_velocity[0]"),
    ("damping_until_minus_inf", [(("mechanics", "mass_damping_until"), float("-inf"))],
     "mechanics.mass_damping_until"),
    ("threads_zero", [(("mechanics", "threads"), 0)], "mechanics.threads"),
    ("threads_above_the_cores", [(("mechanics", "threads"), 10 ** 6)], "mechanics.threads"),
    ("n_5000_digits", [(("coupling",), {"n": 10 ** 4000})], "coupling.n"),
    ("end_int_4000_digits", [(("time", "end"), 10 ** 4000)], "time.end"),
    # issue 33: flow curves and temperatures
    ("flow_table_not_increasing", [(("materials", "paper_al", "yield_stress"), _DELETE),
                                   (("materials", "paper_al", "flow_curve"), dict(FLOW_TABLE, plastic_strain=[0.0, 0.1, 0.05]))],
     "materials.paper_al.flow_curve.plastic_strain[2]"),
    ("flow_table_negative_stress", [(("materials", "paper_al", "yield_stress"), _DELETE),
                                    (("materials", "paper_al", "flow_curve"), dict(FLOW_TABLE, yield_stress=[2e8, -1e6, 3e8]))],
     "materials.paper_al.flow_curve.yield_stress[1]"),
    ("flow_table_negative_strain", [(("materials", "paper_al", "yield_stress"), _DELETE),
                                    (("materials", "paper_al", "flow_curve"), dict(FLOW_TABLE, plastic_strain=[0.0, -0.1, 0.2]))],
     "materials.paper_al.flow_curve.plastic_strain[1]"),
    ("flow_table_temperatures_not_increasing",
     [(("materials", "paper_al", "yield_stress"), _DELETE),
      (("materials", "paper_al", "flow_curve"), dict(FLOW_TABLE, temperatures=[573.0, 293.0],
                                                     yield_stress=[[2e8, 2.5e8, 3e8], [1.5e8, 1.8e8, 2e8]]))],
     "materials.paper_al.flow_curve.temperatures[1]"),
    ("flow_table_curve_count", [(("materials", "paper_al", "yield_stress"), _DELETE),
                                (("materials", "paper_al", "flow_curve"), dict(FLOW_TABLE, strain_rates=[1.0, 1e3]))],
     "materials.paper_al.flow_curve.yield_stress"),
    ("flow_and_linear_law", [(("materials", "paper_al", "flow_curve"), FLOW_TABLE)], "materials.paper_al.yield_stress"),
    ("no_yield_no_flow", [(("materials", "paper_al", "yield_stress"), _DELETE)], "materials.paper_al.yield_stress"),
    ("jc_melting_below_room", [(("materials", "paper_al", "yield_stress"), _DELETE),
                               (("materials", "paper_al", "flow_curve"), dict(FLOW_JC, melting_temperature=250.0))],
     "materials.paper_al.flow_curve.melting_temperature"),
    ("initial_temperature_above_melting", [(("materials", "paper_al", "yield_stress"), _DELETE),
                                           (("materials", "paper_al", "flow_curve"), FLOW_JC),
                                           (("materials", "paper_al", "initial_temperature"), 900.0)],
     "materials.paper_al.initial_temperature"),
    ("jc_with_rate_law", [(("materials", "paper_al", "yield_stress"), _DELETE),
                          (("materials", "paper_al", "flow_curve"), FLOW_JC),
                          (("materials", "paper_al", "rate_law"), {"type": "johnson_cook", "C": 0.01})],
     "materials.paper_al.rate_law"),
    ("taylor_quinney_above_one", [(("materials", "paper_al", "taylor_quinney"), 1.5)], "materials.paper_al.taylor_quinney"),
    ("specific_heat_negative", [(("materials", "paper_al", "specific_heat"), -900.0)], "materials.paper_al.specific_heat"),
    # issue 33: a conductivity that follows temperature
    ("conductivity_table_not_increasing",
     [(("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "conductivity_curve"), dict(COND_TABLE, temperatures=[293.0, 500.0, 400.0]))],
     "materials.paper_al.conductivity_curve.temperatures[2]"),
    ("conductivity_table_negative",
     [(("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "conductivity_curve"), dict(COND_TABLE, conductivities=[3.5e7, -1e7, 2e7]))],
     "materials.paper_al.conductivity_curve.conductivities[1]"),
    ("conductivity_table_lengths",
     [(("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "conductivity_curve"), dict(COND_TABLE, conductivities=[3.5e7, 2e7]))],
     "materials.paper_al.conductivity_curve.conductivities"),
    ("conductivity_table_above_own_melting",
     [(("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "conductivity_curve"), dict(COND_TABLE, melting_temperature=700.0))],
     "materials.paper_al.conductivity_curve.temperatures[2]"),
    ("conductivity_table_above_flow_curve_melting",
     [(("materials", "paper_al", "yield_stress"), _DELETE), (("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "flow_curve"), FLOW_JC),
      (("materials", "paper_al", "conductivity_curve"), dict(COND_TABLE, temperatures=[293.0, 600.0, 900.0]))],
     "materials.paper_al.conductivity_curve.temperatures[2]"),
    ("conductivity_curve_without_specific_heat",
     [(("materials", "paper_al", "conductivity_curve"), COND_TABLE)], "materials.paper_al.conductivity_curve"),
    ("resistivity_coefficient_negative",
     [(("materials", "paper_al", "specific_heat"), 900.0),
      (("materials", "paper_al", "conductivity_curve"), {"type": "linear_resistivity", "temperature_coefficient": -4e-3})],
     "materials.paper_al.conductivity_curve.temperature_coefficient"),
    ("melting_without_specific_heat", [(("materials", "paper_al", "melting_temperature"), 900.0)],
     "materials.paper_al.melting_temperature"),
    ("initial_temperature_above_own_melting", [(("materials", "paper_al", "specific_heat"), 900.0),
                                               (("materials", "paper_al", "melting_temperature"), 280.0)],
     "materials.paper_al.initial_temperature"),
    ("flow_type_unknown", [(("materials", "paper_al", "yield_stress"), _DELETE),
                           (("materials", "paper_al", "flow_curve"), {"type": "zerilli_armstrong"})],
     "materials.paper_al.flow_curve.type"),
]

BAD_OVERRIDES = [
    ("set_string_number", ["time.end=abc"], "time.end"),
    ("set_index_range", ["bodies[5].mesh_size=1"], "bodies[5]"),
    ("set_name_unknown", ["bodies.middle.mesh_size=1"], "bodies.middle"),
    ("set_no_equals", ["time.end"], "time.end"),
    ("set_no_value", ["time.end="], "time.end"),
    ("set_cfl_zero", ["time.cfl=0"], "time.cfl"),
    ("set_h0_negative", ["contact[0].h0=-0.01"], "contact[0].h0"),
    ("set_unknown_key", ["mechanics.viscosity=1"], "mechanics.viscosity"),
    ("set_into_scalar", ["time.end.x=1"], "time.end"),
    ("set_bad_path", ["time..end=1"], "time..end"),
    ("set_index_into_table", ["time[0]=1"], "time[0]"),
    ("set_index_into_body", ["bodies[0][1]=1"], "bodies[0][1]"),
    ("set_smuggled_table", ["time.end=1e-3\n[extra]"], "--set"),
    ("set_smuggled_key", ["time.end=1e-3\rcase.name='x'"], "--set"),
    ("set_control_in_key", ["time.e\x1bnd=1"], "--set"),
    ("set_nested_value", ["time.end=" + "[" * 5000 + "]" * 5000], "time.end"),
    ("set_5000_digits", ["time.end=" + "9" * 5000], "time.end"),
    ("set_name_path", ["case.name='/tmp/x'"], "case.name"),
    ("probe_name_path", ["probes[0].name='../../escape'"], "probes[0].name"),  # it names plots/<name>_*.png
    ("probe_name_long", [f"probes[0].name='{'p' * 300}'"], "probes[0].name"),
    ("set_end_inf", ["time.end=inf"], "time.end"),
    ("set_key_100000_parts", ["a" + ".a" * 100_000 + "=1"], "dotted parts"),
    ("set_value_100000_parts", ["case.description={" + "a." * 100_000 + "b = 1}"], "dotted parts"),
]


#: coupled cases with several conductor bodies: (name, case, --set values, key named in the error)
BAD_COUPLED = [
    ("die_gap_zero", "emf_sheet_die", ["geometry.die.gap=0"], "geometry.die.gap"),
    ("die_fillet_too_big", "emf_sheet_die", ["geometry.die.entry_radius=0.003"], "geometry.die.entry_radius"),
    ("die_body_missing", "emf_sheet_die", ["bodies.die.region='outer_tube'"], "bodies[1].region"),
    ("collar_overlaps_tube", "emf_tube_press_fit", ["geometry.outer_tube.inner_radius=0.018"],
     "geometry.outer_tube.inner_radius"),
    ("planar_axisymmetric", "emf_corner_fill", ["mechanics.formulation='axisymmetric'"], "mechanics.formulation"),
    ("planar_die_above_blank", "emf_corner_fill", ["geometry.die=[[0, 0], [0.1, 0], [0.1, 0.01]]"], "geometry.die"),
    ("bdf2_with_substeps", "emf_sheet_bulge", ["em.time_scheme='bdf2'", "coupling.em_substeps=5"],
     "coupling.em_substeps"),
    ("time_scheme_unknown", "emf_sheet_bulge", ["em.time_scheme='rk4'"], "em.time_scheme"),
    ("damping_with_getdp", "emf_sheet_bulge", ["mechanics.mass_damping=1e4"], "mechanics.mass_damping"),
    ("kinetic_damping_with_getdp", "emf_sheet_bulge", ["mechanics.kinetic_damping_until=1e-5"],
     "mechanics.kinetic_damping_until"),
    # several coils on their own sources (cases/two_coils_plate: sources main, late; coils inner, outer)
    ("coil_without_source", "two_coils_plate", ["em.coils[1]={name = 'outer', sign = -1}"], "em.coils[1].source"),
    ("coil_source_unknown", "two_coils_plate", ["em.coils[1].source='nope'"], "em.coils[1].source"),
    ("source_unused", "two_coils_plate", ["em.coils[1].source='main'"], "em.sources[1].name"),
    ("source_names_twice", "two_coils_plate", ["em.sources[1].name='main'"], "em.sources[1].name"),
    ("coil_names_twice", "two_coils_plate", ["em.coils[1].name='inner'"], "em.coils[1].name"),
    ("geometry_coil_names_twice", "two_coils_plate", ["geometry.coils[1].name='inner'"], "geometry.coils[1].name"),
    ("coil_not_in_geometry", "two_coils_plate", ["em.coils[1].name='middle'"], "em.coils[1].name"),
    ("sign_zero", "two_coils_plate", ["em.coils[1].sign=0"], "em.coils[1].sign"),
    ("two_banks", "two_coils_plate", ["em.sources[0]={name = 'main', type = 'bank', capacitance = 1e-5, voltage = 1e3}",
                                      "em.sources[1]={name = 'late', type = 'bank', capacitance = 1e-5, voltage = 1e3}"],
     "em.sources[1].type"),
    ("bank_beside_a_sine", "two_coils_plate", ["em.sources[0]={name = 'main', type = 'bank', capacitance = 1e-5, "
                                                "voltage = 1e3}"], "em.coils[1].source"),
    ("sources_and_circuit", "two_coils_plate", ["em.circuit={capacitance = 1e-5, voltage = 1e3}"], "em.sources"),
    ("frequency_zero", "two_coils_plate", ["em.sources[0].frequency=0"], "em.sources[0].frequency"),
    ("winding_inverted", "two_coils_plate", ["geometry.coils[0].windings=[[16e-3, -3e-3, 8e-3, 0.0]]"],
     "geometry.coils[0].windings[0]"),
    ("winding_over_the_axis", "two_coils_plate", ["geometry.coils[0].windings=[[-1e-3, -3e-3, 8e-3, 0.0]]"],
     "geometry.coils[0].windings[0]"),
    ("windings_overlap", "two_coils_plate", ["geometry.coils[1].windings=[[15e-3, -3e-3, 20e-3, 0.0]]"],
     "geometry.coils[1].windings[0]"),
    ("winding_in_the_plate", "two_coils_plate", ["geometry.coils[0].windings=[[8e-3, -3e-3, 16e-3, 1.5e-3]]"],
     "geometry.coils[0].windings[0]"),
    ("winding_touches_the_plate", "two_coils_plate", ["geometry.coils[0].windings=[[8e-3, -3e-3, 16e-3, 1e-3]]"],
     "geometry.coils[0].windings[0]"),
    ("workpiece_inverted", "two_coils_plate", ["geometry.workpiece.z1=0.5e-3"], "geometry.workpiece"),
    ("air_too_small", "two_coils_plate", ["geometry.air_radius=0.05"], "geometry.air_radius"),
    ("no_geometry_coils", "two_coils_plate", ["geometry.coils=[]"], "geometry.coils"),
    ("table_not_csv", "two_coils_plate", ["em.sources[0]={name = 'main', type = 'table', file = 'current.txt'}"],
     "em.sources[0].file"),
    ("table_missing", "two_coils_plate", ["em.sources[0]={name = 'main', type = 'table', file = 'missing.csv'}"],
     "em.sources[0].file"),
    ("table_outside", "two_coils_plate", ["em.sources[0]={name = 'main', type = 'table', file = '../../x.csv'}"],
     "em.sources[0].file"),
    # issue 33: the coil's σ(T), repeated shots
    ("coil_conductivity_above_copper_melting", "emf_sheet_bulge",
     ["em.coil_conductivity_curve={type = 'table', temperatures = [293.0, 1500.0], conductivities = [5.8e7, 1e7]}"],
     "em.coil_conductivity_curve.temperatures[1]"),
    ("coil_conductivity_not_increasing", "emf_sheet_bulge",
     ["em.coil_conductivity_curve={type = 'table', temperatures = [400.0, 293.0], conductivities = [4e7, 5.8e7]}"],
     "em.coil_conductivity_curve.temperatures[1]"),
    ("coil_initial_temperature_above_melting", "emf_sheet_bulge",
     ["em.coil_conductivity_curve={type = 'linear_resistivity', temperature_coefficient = 3.9e-3}",
      "em.coil_initial_temperature=1400.0"], "em.coil_initial_temperature"),
    ("shots_voltage_count", "emf_sheet_bulge", ["em.shots={count = 3, pause = 1.0, voltages = [6e3]}"],
     "em.shots.voltages"),
    ("shots_pause_zero", "emf_sheet_bulge", ["em.shots={count = 3, pause = 0.0}"], "em.shots.pause"),
    ("shots_without_bank", "two_coils_plate", ["em.shots={count = 2, pause = 1.0}"], "em.shots"),
    ("shots_on_a_user_deck", "user_deck_sheet_bulge", ["em.shots={count = 2, pause = 1.0}"], "em.shots"),
    # issue 34 item 4: ten-node tetrahedra in 3D cases, mechanics-only and coupled (walls and contact too: see
    # test_tet10_walls_and_contact_are_accepted; pressure pulses: test_tet10_pressure_pulses_are_accepted)
    ("tet10_in_2d", "bar_impact", ["bodies[0].element='tet10'"], "bodies[0].element"),
    ("element_unknown", "bar_impact_3d", ["bodies[0].element='hex8'"], "bodies[0].element"),
    # the 2D half: six-node triangles in 2D cases, mechanics-only and coupled (walls, contact and the forming
    # limit too: see test_tri6_walls_and_contact_are_accepted, test_tri6_coupled_and_forming_limit_are_accepted)
    ("tri6_in_3d", "bar_impact_3d", ["bodies[0].element='tri6'"], "bodies[0].element"),
]


@pytest.mark.parametrize("name,case,sets,key", BAD_COUPLED, ids=[b[0] for b in BAD_COUPLED])
def test_bad_coupled_override(capsys, name, case, sets, key):
    args = ["check", str(REPO / "cases" / case)]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    _assert_one_line_error(capsys, rc, key, "case.toml")


def test_tet10_walls_and_contact_are_accepted():
    """Ten-node bodies on rigid walls and in contact pairs (issue 34 item 4; refused before): the case's
    validation, where the refusal was, passes for the 3D bar on its wall and the two bars in contact."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "bar_impact_3d", ["bodies[0].element='tet10'"])
    assert case.bodies[0].element == "tet10" and case.walls
    case, _ = load_case(REPO / "cases" / "bar_impact_3d" / "two_bodies.toml",
                        ["bodies[0].element='tet10'", "bodies[1].element='tet10'"])
    assert {b.element for b in case.bodies} == {"tet10"} and case.contact


def test_tet10_pressure_pulses_are_accepted():
    """Pressure pulses on a ten-node body (refused before the six-node faces took their consistent loads,
    tests/mechanics/test_tet10_pressure.py): the case's validation passes."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "emf_sheet_bulge_3d", [
        "bodies[0].element='tet10'", 'coupling.load="pressure"',
        'loads=[{type="pulse_sin2", body="sheet", surface={zmin=1.4999e-3, zmax=1.5001e-3}, amplitude=8.7e6, '
        'beta=8.9e3, omega=9.3e4, t_end=60e-6}]'])
    assert case.bodies[0].element == "tet10" and case.loads


def test_tri6_is_accepted_in_a_mechanics_only_2d_case():
    """Six-node triangles (issue 34 item 4, the 2D half) pass the validation of a 2D mechanics-only case with
    pressure pulses (its bodies take them on their three-node edges)."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "cantilever_two_pulses", ["bodies[0].element='tri6'"])
    assert case.bodies[0].element == "tri6" and case.loads


def test_tri6_walls_and_contact_are_accepted():
    """Six-node bodies on rigid walls and in contact pairs (refused before; tests/mechanics/test_tri6_contact.py):
    the case's validation, where the refusal was, passes for the bar on its wall and the two bars in contact."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "bar_impact_wall", ["bodies[0].element='tri6'"])
    assert case.bodies[0].element == "tri6" and case.walls
    case, _ = load_case(REPO / "cases" / "bar_impact", ["bodies[0].element='tri6'", "bodies[1].element='tri6'"])
    assert {b.element for b in case.bodies} == {"tri6"} and case.contact


def test_tri6_coupled_and_forming_limit_are_accepted():
    """Six-node bodies in a coupled 2D case (refused before; the transfer: tests/coupling/test_transfer_tri6.py) and
    with a forming-limit curve (the demo's sheet has one; the check reads the corners): the validation passes."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "emf_sheet_bulge", ["bodies[0].element='tri6'"])
    assert case.case.kind == "coupled" and case.bodies[0].element == "tri6"
    assert case.materials[case.bodies[0].material].forming_limit is not None


def test_tet10_soft_contact_with_the_implicit_integrator_is_accepted():
    """Ten-node soft contact with the implicit integrator (refused while its Newton iterations stalled; they
    converge since a node keeps its master face near shared edges: tests/mechanics/test_implicit_contact.py):
    the case's validation passes."""
    from pulseform.orchestrator.case.io import load_case

    case, _ = load_case(REPO / "cases" / "bar_impact_3d" / "two_bodies.toml",
                        ["bodies[0].element='tet10'", "mechanics.integrator='implicit'", "mechanics.implicit.dt=1e-5"])
    assert case.bodies[0].element == "tet10" and case.contact and case.mechanics.integrator == "implicit"


def test_conductivity_curve_in_3d_is_accepted(capsys):
    """σ(T) runs in 3D on either getdp ('auto' picks the persistent one with bdf2, whose step messages carry σ per
    element; 'persistent' was refused in 3D before): no longer refused. The whole check (the 3D geometry meshed,
    the deck's own refusals asked) for 'persistent'; the case's validation, where the refusal was, for the others."""
    from pulseform.orchestrator.case.io import load_case

    curve = "em.coil_conductivity_curve={type = 'linear_resistivity', temperature_coefficient = 3.9e-3}"
    rc = main(["check", str(REPO / "cases" / "emf_sheet_bulge_3d"), "--set", curve,
               "--set", "em.getdp_process='persistent'"])
    assert rc == 0, capsys.readouterr().err
    for process in ("auto", "per_step"):
        case, _ = load_case(REPO / "cases" / "emf_sheet_bulge_3d", [curve, f"em.getdp_process='{process}'"])
        assert case.em.getdp_process == process and case.em.coil_conductivity_curve is not None


def test_shots_in_3d_are_accepted(capsys):
    """[em.shots] runs in 3D too (the 3D load cools its coil and the bodies between shots): no longer refused."""
    rc = main(["check", str(REPO / "cases" / "emf_sheet_bulge_3d"), "--set", "em.shots={count = 2, pause = 1.0}"])
    assert rc == 0, capsys.readouterr().err


def test_conductivity_curve_on_the_persistent_getdp_is_accepted(capsys):
    """σ(T) runs on the persistent getdp too (its step messages carry σ per element): no longer refused."""
    rc = main(["check", str(REPO / "cases" / "emf_sheet_bulge"), "--set",
               "em.coil_conductivity_curve={type = 'linear_resistivity', temperature_coefficient = 3.9e-3}",
               "--set", "em.time_scheme='bdf2'", "--set", "em.getdp_process='persistent'"])
    assert rc == 0, capsys.readouterr().err


def _write(tmp_path: Path, data: dict, name: str = "case.toml") -> Path:
    p = tmp_path / name
    p.write_text(tomli_w.dumps(data))
    return p


def _assert_one_line_error(capsys, rc: int, must_contain: str, file_hint: str) -> str:
    out, err = capsys.readouterr()
    assert rc == 2, f"exit code {rc}, stderr: {err}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("pulseform: error: ")
    assert len(lines[0]) <= 300, lines[0]
    assert must_contain in lines[0], lines[0]
    assert file_hint in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize("name,edits,key", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_case_file(tmp_path, capsys, name, edits, key):
    data = copy.deepcopy(BASE)
    for path, value in edits:
        _set(data, path, value)
    file = _write(tmp_path, data)
    rc = main(["check", str(file)])
    _assert_one_line_error(capsys, rc, key, str(file))


@pytest.mark.parametrize("name,sets,key", BAD_OVERRIDES, ids=[b[0] for b in BAD_OVERRIDES])
def test_bad_override(capsys, name, sets, key):
    args = ["check", str(REPO / "cases/bar_impact")]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    _assert_one_line_error(capsys, rc, key, "case.toml")


def test_toml_syntax_error_names_line(tmp_path, capsys):
    file = tmp_path / "case.toml"
    file.write_text("[time]\nend = 1e-3\ncfl = \n")
    rc = main(["check", str(file)])
    line = _assert_one_line_error(capsys, rc, "line 3", str(file))
    assert "TOML syntax error" in line


def test_missing_case_file(tmp_path, capsys):
    rc = main(["check", str(tmp_path / "nowhere")])
    _assert_one_line_error(capsys, rc, "no case file found", "nowhere")


def test_distinct_bad_inputs_count():
    """The issue asks for at least 25 distinct bad files / overrides."""
    assert len(BAD_FILES) + len(BAD_OVERRIDES) >= 25


def test_valid_override_round_trip(capsys):
    rc = main(["check", str(REPO / "cases/bar_impact"), "--set", "bodies.left.mesh_size=0.25",
               "--set", "time.end=1e-3"])
    out, _ = capsys.readouterr()
    assert rc == 0
    resolved = tomllib.loads(out.split("\n", 1)[1])
    assert resolved["bodies"][0]["mesh_size"] == 0.25
    assert resolved["time"]["end"] == 1e-3


def test_run_goes_through_the_same_validation(tmp_path):
    """The real console script, as a user runs it: exit 2, one line, no traceback."""
    exe = Path(sys.executable).with_name("pulseform")
    r = subprocess.run([str(exe), "run", str(REPO / "cases/bar_impact"), "--out", str(tmp_path / "o"),
                        "--set", "contact[0].h0=0"], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0
    assert "contact[0].h0" in r.stderr
    assert not (tmp_path / "o").exists(), "a rejected case must not create a results folder"


# ----------------------------------------------------------------------------- generated inputs
# Numeric keys with a lower bound, and a violating value for each.
BOUNDED = [
    (("time", "end"), 0.0, True), (("time", "cfl"), 0.0, True), (("bodies", 0, "mesh_size"), 0.0, True),
    (("contact", 0, "h0"), 0.0, True), (("contact", 0, "stiffness"), 0.0, True),
    (("contact", 0, "friction"), 0.0, False), (("materials", "paper_al", "density"), 0.0, True),
    (("materials", "paper_al", "bulk_modulus"), 0.0, True),
    (("materials", "paper_al", "hardening_modulus"), 0.0, False),
    (("mechanics", "thickness"), 0.0, True), (("bodies", 1, "shape", "width"), 0.0, True),
]


def _path_text(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(BOUNDED),
       below=st.floats(min_value=1e-300, max_value=1e30, allow_nan=False, allow_infinity=False))
def test_generated_out_of_range(tmp_path, capsys, which, below):
    path, bound, exclusive = which
    value = bound - below if not exclusive else bound - below * (below > 0)
    data = copy.deepcopy(BASE)
    _set(data, path, value)
    file = _write(tmp_path, data, "gen.toml")
    rc = main(["check", str(file)])
    _assert_one_line_error(capsys, rc, _path_text(path), str(file))


JUNK = st.one_of(st.text(max_size=8), st.booleans(), st.integers(-5, 5),
                 st.floats(allow_nan=True, allow_infinity=True),
                 st.lists(st.integers(), max_size=3), st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
LEAVES = [("time", "end"), ("time", "cfl"), ("case", "name"), ("case", "kind"), ("bodies", 0, "shape"),
          ("bodies", 0, "initial_velocity"), ("contact", 0), ("mechanics", "formulation"),
          ("materials", "paper_al"), ("probes", 0, "point"), ("output",), ("bodies", 1, "fixed")]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(LEAVES), value=JUNK)
def test_generated_junk_never_tracebacks(tmp_path, capsys, path, value):
    """Any junk at any key: either valid (0) or a one-line error naming that key (2)."""
    data = copy.deepcopy(BASE)
    _set(data, path, value)
    try:
        file = _write(tmp_path, data, "junk.toml")
    except (TypeError, ValueError):  # not representable in TOML (e.g. nan keys), nothing to test
        return
    rc = main(["check", str(file)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    assert rc in (0, 2)
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1
        assert lines[0].startswith("pulseform: error: ")


# ----------------------------------------------------------------------------- issue 13: inputs that once gave tracebacks
def test_deeply_nested_toml(tmp_path, capsys):
    file = tmp_path / "deep.toml"
    file.write_text((REPO / "cases/bar_impact/case.toml").read_text() + "\nx = " + "[" * 5000 + "]" * 5000 + "\n")
    _assert_one_line_error(capsys, main(["check", str(file)]), "nested too deeply", str(file))


def test_5000_digit_integer_in_file(tmp_path, capsys):
    file = tmp_path / "digits.toml"
    file.write_text((REPO / "cases/bar_impact/case.toml").read_text().replace("[time]\n", "[time]\nn = " + "7" * 5000
                                                                             + "\n", 1))
    _assert_one_line_error(capsys, main(["check", str(file)]), "4300 digits", str(file))


def test_long_and_nul_case_paths(tmp_path, capsys):
    long = str(tmp_path / ("x" * 5000))
    line = _assert_one_line_error(capsys, main(["check", long]), "too long", str(tmp_path))
    assert "…" in line
    line = _assert_one_line_error(capsys, main(["check", str(tmp_path / "a\x00b.toml")]), "no case file", "a\\x00b")
    assert "\x00" not in line


def test_unusable_out_folders(tmp_path, capsys):
    """--out that cannot be a folder (a 300-character name, a file in the path) is bad input for run
    and sweep: exit 2, one short line, nothing created (issue 13: was an internal error, exit 1)."""
    long = str(tmp_path / ("p" * 300))
    (tmp_path / "file").write_text("x")
    case = str(REPO / "cases/bar_impact")
    for argv, why in ((["run", case, "--out", long, "--quiet"], "File name too long"),
                      (["sweep", case, "--param", "time.end=1e-5,2e-5", "--out", long], "File name too long"),
                      (["run", case, "--out", str(tmp_path / "file" / "x"), "--quiet"], "Not a directory")):
        line = _assert_one_line_error(capsys, main(argv), "cannot be a results folder", why)
        assert len(line) <= 300, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_user_deck_path_tricks(capsys):
    deck = str(REPO / "cases/user_deck_sheet_bulge")
    for value, key in (("'a" + "b" * 5000 + ".geo'", "geometry.mesh"), ('"sheet\\u0000bulge.pro"', "geometry.pro")):
        _assert_one_line_error(capsys, main(["check", deck, "--set", f"{key}={value}"]), key, "case.toml")


def test_default_infinities_are_accepted(tmp_path, capsys):
    """inf where the default is inf (Box bounds, mass_damping_until), so `check`'s own output reads back."""
    data = copy.deepcopy(BASE)
    data["mechanics"]["mass_damping_until"] = float("inf")
    data["bodies"][0]["fixed"] = [{"where": {"xmin": float("-inf"), "xmax": 0.0}, "components": [0]}]
    rc = main(["check", str(_write(tmp_path, data))])
    out, err = capsys.readouterr()
    assert rc == 0, err
    again = tmp_path / "again.toml"
    again.write_text(out.split("\n", 1)[1])
    assert "-inf" in again.read_text()
    assert main(["check", str(again)]) == 0, capsys.readouterr().err


def test_shipped_cases_pass():
    for file in sorted((REPO / "cases").glob("*/*.toml")):
        load_case(file)


def test_every_unit_has_a_plausible_range():
    units = {unit for _, allowed, unit, _, _ in reference_rows(Case) if "number" in allowed or "integer" in allowed}
    assert units - {""} <= set(PLAUSIBLE), units - set(PLAUSIBLE)


def test_case_file_reference_lists_the_plausible_ranges():
    page = (REPO / "docs/reference/case-file.md").read_text()
    for unit, (lo, hi) in PLAUSIBLE.items():
        assert f"| `{unit}` | {lo:g} | {hi:g} |" in page, unit


def test_key_of_100000_parts_in_file(tmp_path, capsys):
    """tomllib needs minutes and gigabytes for it; refused before parsing."""
    file = tmp_path / "dotted.toml"
    file.write_text((REPO / "cases/bar_impact/case.toml").read_text() + "\n" + ".".join(["a"] * 100_000) + " = 1\n")
    _assert_one_line_error(capsys, main(["check", str(file)]), "dotted parts", str(file))
    file.write_text('[case]\nname = "ok"\ndescription = "' + "a." * 100 + 'b"\n')  # in a string: no key
    main(["check", str(file)])
    assert "dotted parts" not in capsys.readouterr().err


def test_huge_file(tmp_path, capsys):
    file = tmp_path / "huge.toml"
    file.write_text("x = [" + "1.5, " * 600_000 + "]\n")
    _assert_one_line_error(capsys, main(["check", str(file)]), "MiB", str(file))


def test_thin_part_caps_the_element_size_of_the_guards(capsys):
    """A 1 µm sheet "meshed at 0.5 mm" gets 1 µm elements: ~7e4 getdp runs for the demo's 60 µs. Found by
    the slow fuzz tier (it ran for more than 10 minutes); the guards now use the thickness (guards.py)."""
    from pulseform.orchestrator.cli import main

    code = main(["check", str(REPO / "cases/emf_sheet_bulge"), "--set", "geometry.sheet_thickness=1e-6"])
    err = capsys.readouterr().err
    assert code == 2 and "limits.max_em_steps" in err and "capped by the part's thickness" in err, err
    code = main(["check", str(REPO / "cases/emf_sheet_bulge"), "--set", "geometry.sheet_thickness=1e-6",
                 "--set", "limits.max_em_steps=1e6"])
    assert code == 0, capsys.readouterr().err


#: a ``table`` source's CSV file that the loader refuses: (id, file text, what the message says)
BAD_TABLES = [
    ("not_monotonic", "0,0\n2e-6,1e3\n1e-6,2e3\n", "strictly increasing"),
    ("repeated_time", "0,0\n1e-6,1e3\n1e-6,2e3\n", "strictly increasing"),
    ("not_numbers", "time,current\n0,0\n1e-6,lots\n", "not two numbers"),
    ("three_columns", "0,0,1\n1e-6,1e3,1\n", "3 columns"),
    ("one_row", "0,5\n", "at least 2"),
    ("starts_late", "1e-6,0\n2e-6,1e3\n", "start at or before t = 0"),
    ("not_finite", "0,0\n1e-6,nan\n", "finite"),
    ("huge_current", "0,0\n1e-6,1e12\n", "current"),
    ("empty", "", "0 data rows"),
]


@pytest.mark.parametrize("command", ["check", "run"])
@pytest.mark.parametrize("name,text,says", BAD_TABLES, ids=[b[0] for b in BAD_TABLES])
def test_bad_table_source(tmp_path, capsys, name, text, says, command):
    """A table source's file: one line naming em.sources[0].file and what is wrong, exit 2, from check and run."""
    data = tomllib.loads((REPO / "cases/two_coils_plate/case.toml").read_text())
    data["em"]["sources"][0] = {"name": "main", "type": "table", "file": "current.csv"}
    (tmp_path / "current.csv").write_text(text)
    file = _write(tmp_path, data)
    args = [command, str(file)] + (["--out", str(tmp_path / "out")] if command == "run" else [])
    line = _assert_one_line_error(capsys, main(args), "em.sources[0].file", str(file))
    assert says in line, line
    assert not (tmp_path / "out").exists()


def test_table_outside_the_case_folder_is_allowed_when_asked(tmp_path, capsys):
    """allow_outside = true takes a table from another folder (as user decks' mesh/pro); the resolved case
    holds its absolute path."""
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "i.csv").write_text("0,0\n1e-5,1e3\n")
    (tmp_path / "case").mkdir()
    data = tomllib.loads((REPO / "cases/two_coils_plate/case.toml").read_text())
    data["em"]["sources"][0] = {"name": "main", "type": "table", "file": "../tables/i.csv"}
    file = _write(tmp_path / "case", data)
    _assert_one_line_error(capsys, main(["check", str(file)]), "em.sources[0].file", str(file))
    data["em"]["sources"][0]["allow_outside"] = True
    case, _ = load_case(_write(tmp_path / "case", data))
    assert case.em.sources[0].file == str((tmp_path / "tables" / "i.csv").resolve())


@pytest.mark.parametrize("name,case,sets,key", [b for b in BAD_COUPLED if b[1] == "two_coils_plate"][:4],
                         ids=[b[0] for b in BAD_COUPLED if b[1] == "two_coils_plate"][:4])
def test_bad_sources_refused_by_run(tmp_path, capsys, name, case, sets, key):
    """``pulseform run`` refuses bad sources and coils like ``check`` (exit 2, one line), before any output."""
    args = ["run", str(REPO / "cases" / case), "--out", str(tmp_path / "out")]
    for s in sets:
        args += ["--set", s]
    _assert_one_line_error(capsys, main(args), key, "case.toml")
    assert not (tmp_path / "out").exists()


def test_two_coils_on_a_one_coil_geometry(tmp_path, capsys):
    """The built-in geometries other than coaxial_coils have one coil: a second [[em.coils]] entry is refused."""
    data = tomllib.loads((REPO / "cases/emf_sheet_bulge/case.toml").read_text())
    del data["em"]["circuit"]
    data["em"]["sources"] = [{"name": "a", "type": "dc", "current": 1e3}, {"name": "b", "type": "dc", "current": 1e3}]
    data["em"]["coils"] = [{"name": "a", "source": "a"}, {"name": "b", "source": "b"}]
    file = _write(tmp_path, data)
    _assert_one_line_error(capsys, main(["check", str(file)]), "em.coils[1]", str(file))
    data["em"]["sources"], data["em"]["coils"] = data["em"]["sources"][:1], data["em"]["coils"][:1]
    case, _ = load_case(_write(tmp_path, data))  # one coil on a source: fine
    assert case.em.coils[0].source == "a"
