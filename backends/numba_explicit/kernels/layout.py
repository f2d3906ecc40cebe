"""Index layout of the small arrays the numba kernels share with Python (plain constants).

Numba freezes module-level integers into compiled code, so these names cost nothing at run time.
``par`` (float64) holds run parameters, ``ipar`` (int64) switches, ``sc`` (float64) the scalar
state that survives between calls of the time loop, and each row of ``hist`` one time step.
"""

# LLVM fast-math flags of every kernel: reciprocal approximation of divisions (arcp), fused
# multiply-add (contract), no signed zeros (nsz); about 10 % faster. Deliberately *not* nnan /
# ninf: the kernels must still see inf and NaN to report overflow and inversion. Every kernel
# also uses error_model="numpy": a division by zero gives inf / NaN (caught by the finiteness
# checks) instead of a per-division test raising ZeroDivisionError.
FASTMATH = {"arcp", "contract", "nsz"}
# The unrolled corner sums (element.UNROLLED_CORNERS) without nsz: 0 + x b then stays a fused
# multiply-add, as in a loop, so that the sums round as they do element by element.
FASTMATH_SUMS = {"arcp", "contract"}

# ---- par: run parameters (SI units) ----
P_RHO = 0           # density (kg/m^3)
P_HG = 1            # hourglass coefficient Q_hg (-)
P_SAFETY = 2        # time-step safety factor on L / c (-)
P_DTMAX = 3         # upper bound of the time step (s)
P_COLLAPSE = 4      # time-step collapse threshold, fraction of the first step (-)
P_RADIUS = 5        # sphere radius (m)
P_SMASS = 6         # sphere mass of the modelled part (kg)
P_CX = 7            # sphere centre x (m)
P_CY = 8            # sphere centre y (m)
P_PLANEZ = 9        # plane height (m)
P_MU = 10           # Coulomb friction coefficient (-)
P_GRAV = 11         # downward gravity on the sphere (m/s^2)
P_SYM = 12          # symmetry factor (-)
P_TEND = 13         # end time (s)
P_SEPTIME = 14      # time after separation before stopping (s)
P_GINF = 15         # Prony long-term coefficient gamma_inf (-) (of the first part; each part's in PP_GINF)
P_EDGE = 16         # rim radius of a flat impactor (m)
P_N = 17

# ---- ipar: switches ----
I_HGWAVE = 0        # 0: hourglass wave speed from the isochoric modulus, 1: full longitudinal
I_SPHERE = 1        # 1 if a rigid sphere exists
I_PLANE = 2         # 1 if a rigid plane exists
I_PRESC = 3         # 1 if prescribed motion exists
I_PDOF = 4          # prescribed dof (0, 1, 2)
I_STOPSEP = 5       # 1: stop after separation
I_GENERAL = 6       # 0: hemisphere moving along z (sphere_contact); 1: any shape or motion (impactor_contact)
I_SHAPE = 7         # impactor shape: SH_* below
I_MOVX = 8          # 1 if the impactor moves in x
I_MOVY = 9          # 1 if the impactor moves in y
I_MOVZ = 10         # 1 if the impactor moves in z
I_N = 11

# ---- impactor shapes (ipar[I_SHAPE]), formulas of cfm_core.scene.impactor.gap ----
SH_HEMISPHERE = 0
SH_SPHERE = 1
SH_FLAT = 2
SH_PLANE = 3

# ---- sc: scalar state carried between calls ----
S_T = 0             # time t^n (s)
S_DTPREV = 1        # previous step dt_{n-1/2} (s)
S_Z = 2             # sphere centre z (m)
S_V = 3             # sphere velocity v^{n-1/2} (m/s)
S_IE = 4            # internal energy, trapezoid stress work (J, modelled part)
S_WINT = 5          # accumulated work of internal forces (J)
S_WHG = 6           # ... of hourglass forces
S_WC = 7            # ... of contact constraint forces
S_WEXT = 8          # ... of prescribed motion and gravity
S_IMP = 9           # accumulated contact impulse on the sphere (N s, modelled part)
S_DT0 = 10          # first stable step (s), reference for collapse detection
S_SEEN = 11         # 1 once the contact force has been positive
S_SEPT = 12         # time separated so far (s)
S_STEPS = 13        # number of steps taken
S_ERRE = 14         # element (or node) of an error
S_ERRV = 15         # value of an error (J, dt, ...)
S_ERRM0 = 16        # eigenvalues of C at an error
S_ERRM1 = 17
S_ERRM2 = 18
S_DTMIN = 19        # smallest / largest step taken (s)
S_DTMAX = 20
S_KE0 = 21          # kinetic energy at t = 0 (J)
S_MAXPEN = 22       # largest sphere penetration after correction (m)
S_X = 23            # impactor reference point x, y (m)
S_Y = 24
S_VX = 25           # impactor velocity x, y v^{n-1/2} (m/s)
S_VY = 26
S_N = 27

# ---- hist columns (one row per step; forces, impulses and energies of the full model) ----
H_T = 0             # t^n (s)
H_F = 1             # contact force on the impactor, + decelerating (N)
H_IMP = 2           # impulse int_0^t F dt (N s)
H_Z = 3             # impactor centre z (m)
H_V = 4             # impactor velocity (m/s)
H_R = 5             # reaction force at prescribed nodes (N)
H_KE = 6            # kinetic energy (J)
H_IE = 7            # internal energy (J)
H_HG = 8            # hourglass energy (J)
H_C = 9             # contact energy (J)
H_EXT = 10          # external work (J)
H_WINT = 11         # work of the internal nodal forces (J), diagnostic
H_DT = 12           # step dt_{n+1/2} taken from t^n (s)
H_PEN = 13          # largest sphere penetration after correction (m)
H_PZ = 14           # z momentum of nodes + sphere (kg m/s, full model)
H_FX = 15           # in-plane contact force on the impactor x, y (N; 0 where it is held)
H_FY = 16
H_X = 17            # impactor reference point x, y (m)
H_Y = 18
H_VX = 19           # impactor velocity x, y (m/s)
H_VY = 20
H_PX = 21           # x, y momentum of nodes + impactor (kg m/s, full model; 0 unless it moves laterally)
H_PY = 22
H_N = 23

# ---- the parts: the time loop's ``parts`` is a tuple with one tuple per part (one contiguous
# range of internal elements, its blocks a contiguous range of the block arrays), entries: ----
PT_CONN = 0         # (e_p, 8) int32 corner nodes
PT_SLOT = 1         # (e_p, 8) int32 force-buffer rows
PT_CHUNKS = 2       # (c_p + 1, 3) int64 the part's chunks (first block counted in the part)
PT_ED = 3           # the part's stretch of the block array ed
PT_EH = 4           # its Prony state (6 k_p rows per block)
PT_STATUS = 5       # (e_p,) int8 failure status
PT_BDT = 6          # (nblk_p,) smallest L / c per block (s)
PT_BEMIN = 7        # (nblk_p,) int64 its element (counted in the part)
PT_ERRV = 8         # (nblk_p, 4) values of a failure
PT_P = 9            # material parameters
PT_GAM = 10         # Prony gamma_k, tau_k (s), and the step's decay and gain factors (k_p,)
PT_TAU = 11
PT_DECAY = 12
PT_GAIN = 13
PT_PAR = 14         # float64 values PP_*
PP_RHO = 0          # density (kg/m^3)
PP_GINF = 1         # gamma_inf (-)
PP_E0 = 2           # first internal element of the part
PP_MAT = 3          # index of its material among the module's (codegen.distinct)
PP_N = 4

# ---- return codes of the time loop ----
R_CHUNK = 0         # reached the requested time or buffer end
R_DONE = 1          # end time reached
R_SEPARATED = 2     # impactor separated
R_INVERTED = 10     # element with J <= 0
R_NONFINITE = 11    # non-finite material derivative / stress
R_COLLAPSE = 12     # time-step collapse
R_STATE = 13        # non-finite kinematic state

# ---- element blocks (kernels/element.py) ----
# Elements are processed in blocks of BLOCK; each block's data is one stretch of the flat array
# ``ed`` (ED_N rows of BLOCK values, element i of the block in column i), its Prony state one
# stretch of ``eh`` (6 k rows, row 6 j + c), and the per-step intermediate values a scratch
# array of W_N rows (rows W_FN + c: internal force c = 0..2, hourglass force 3..5 at one corner,
# N, from which the block adds its forces onto the nodes corner by corner; see element.py).
# Row offsets are compile-time constants: LLVM then proves that a stage's stores never overlap
# its loads and vectorises the loops over the columns (with 2-D arrays or one array per quantity
# it would need a run-time overlap check per pair and gives up).
BLOCK = 32
# From this many blocks on (20 480 elements, ~12 MB of block state) each block prefetches the ed and
# eh of the block after the next during its corner stage (element.element_block). Below, the state
# stays in the caches and the prefetches only cost instructions: measured 5 % slower at 5 000
# elements, 1-9 % faster at 40 000 and 13-15 % at 138 624 (docs/user/performance.md).
PREFETCH_BLOCKS = 640
ED_B = 0            # B_a,k (1/m), 24 rows, row 3 a + k
ED_HX = 24          # h_alpha . X_k (m), 12 rows, row 3 alpha + k: the hourglass vectors are
                    # gamma_a,alpha = h_alpha,a - sum_k (h_alpha . X_k) B_a,k (12 values, not 32)
ED_V0 = 36          # reference volume (m^3)
ED_L = 37           # characteristic length (m)
ED_HGF = 38         # rho V0^(2/3) / 4 (kg / m)
ED_S0 = 39          # isochoric S0 of the previous step (Pa), 6 rows (11, 22, 33, 12, 23, 13)
ED_SO = 45          # S of the previous step (Pa), 6 rows
ED_EO = 51          # E = (C - I) / 2 of the previous step (-), 6 rows
ED_N = 57
# hourglass base vectors h_alpha at the 8 corners (xi eta, eta zeta, zeta xi, xi eta zeta; VTK order)
H0 = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0)
H1 = (1.0, 1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0)
H2 = (1.0, -1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0)
H3 = (-1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0)
ENERGY_RANGE = 4096  # nodes per range of the energy sums (element.energy_pass): fixed, so thread-independent
NF = 6              # values per node in the force buffer: internal force x, y, z, hourglass x, y, z (N)
W_F = 0             # F, 9 rows (row-major)
W_Q = 9             # hourglass modes q_alpha,i (m/s), 12 rows, row 3 alpha + i
W_C = 21            # C = F^T F, 6 rows
W_G = 21            # during the kinematics only: the corners' x then v gathered, 48 rows, row 6 a + c
                    # (m, m/s; rows W_C.. W_C + 47 are written by the later stages)
W_J = 27            # det F
W_M = 28            # eigenvalues of C, 3 rows
W_V = 31            # eigenvectors of C (Q row-major, column k for m_k), 9 rows
W_OK = 40           # 1 where the branch-free eigen-decomposition applied
W_R = 41            # psi_grad_hess_diag: 6 first, 6 second derivatives (Pa), 12 rows
W_ST = 53           # status: 0 ok, 1 inverted, 2 non-finite (as a float)
W_SI = 54           # isochoric S0 of this step (Pa), 6 rows
W_D = 60            # S0 - S0_old (Pa), 6 rows
W_S = 66            # S (Pa), 6 rows
W_MT = 72           # largest longitudinal modulus (Pa)
W_MI = 73           # its isochoric part (Pa)
W_DTE = 74          # L / c (s)
W_WORK = 75         # stress work of the step (J)
W_P = 76            # P = F S (Pa), 9 rows (row-major); 0 for failed elements
W_CHG = 85          # hourglass damping -c_hg (kg/s); 0 for failed elements
W_HR = 86           # -c_hg sum_alpha (h_alpha . X_k) q_alpha,i (N), 9 rows, row 3 k + i
W_FN = 95           # nodal forces of one corner of the block's elements (N), 6 rows
W_N = 101           # (wk + the block's ed and eh: ~45 kB, within a 48 kB L1 data cache)
