"""The compiled kernels' shared conventions: the fast-math flags and the layout of the float64
parameter vector of a body (:func:`.kernels.pack_parameters`), in one place for the element kernels
(:mod:`.element_math`, :mod:`.tet_kernel`) and the flow curves (:mod:`.flow_curves`)."""
from __future__ import annotations

__all__ = ["FM", "P_RHO", "P_G", "P_K", "P_SY0", "P_H", "P_RATE", "P_R1", "P_R2", "P_B1", "P_B2",
           "P_BULK", "P_THICK", "P_MODE", "P_FLOW", "P_THERM", "P_BETA", "P_RHOCP", "P_T0", "P_SYF",
           "P_FP", "N_PRM"]

# fast-math: only "no signed zeros". Reassociation, contraction (FMA) and reciprocal approximation let LLVM
# optimise the kernel differently where numba inlines it (a caller compiled now or loaded from the cache):
# results then depended on the cache state (docs/mechanics.md). No nnan/ninf: NaN/inf checks must work.
#: Helpers of the kernels are plain ``numba.njit`` functions, not ``inline="always"``: numba's own (IR-level)
#: inlining deep-copies a callee's IR at every call site, which made the kernels' cold compile ~30 % longer
#: (the tier's compiled tests: 97 -> 75 s of CPU), while LLVM inlines these small functions anyway; the
#: results are the same bits (no fast-math reassociation or contraction: FM). Kept only for the 3D kernel's
#: two tuple helpers (tet_kernel._cross, _norm2).
FM = {"nsz"}

#: density (kg/m^3), shear and bulk moduli (Pa), linear law sigma_0 (Pa) and A (Pa), rate law id and
#: its two parameters, bulk viscosity b1, b2 and on/off, thickness (m), formulation mode
P_RHO, P_G, P_K, P_SY0, P_H, P_RATE, P_R1, P_R2, P_B1, P_B2, P_BULK, P_THICK, P_MODE = range(13)
#: flow law id (:mod:`.flow_curves`, 0 the linear law), temperature tracked (1) or not (0),
#: Taylor-Quinney coefficient beta (-), rho c_p (J/(m^3 K)), initial temperature (K), the lower bound
#: of the yield stress over the strain rates at zero plastic strain and the initial temperature (Pa,
#: :func:`.flow_curves.flow_floor`: the vectorised kernels' screen of a cell that has not yielded)
P_FLOW, P_THERM, P_BETA, P_RHOCP, P_T0, P_SYF = range(13, 19)
#: first of the flow law's own parameters (:func:`.flow_curves.encode`)
P_FP = 19
#: length of the parameter vector without the flow law's own parameters
N_PRM = P_FP
