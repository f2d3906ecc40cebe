"""LS-DYNA interface: ``umat4N`` and ``utan4N`` (N = 41..50) with ``IHYPER = 1`` for solid elements.

Calling convention of LS-DYNA's user-material package (dyn21umats.f, R10 and later):
``umat4N(cm, eps, sig, epsp, hsv, dt1, capa, etype, tt, temper, failel, crv, nnpcrv, cma, qmat,
elsiz, idele, reject)``. With ``IHYPER = 1`` LS-DYNA stores the deformation gradient in
``hsv(NHV+1 .. NHV+9)`` column by column (F11, F21, F31, F12, ...); ``sig`` is the Cauchy stress,
order xx, yy, zz, xy, yz, zx (docs/conventions.md section 7). ``hsv(1 .. NHV)`` hold the Prony
history and the error code; ``NHV`` on the card must be exactly the number written in the header
and in the manifest, or F is read from the wrong place (the routine cannot tell).

An error keeps the stress of the previous step, writes the code into the last user history
variable and a line to unit 6, and sets ``reject`` (an implicit step is then retried with a
smaller step; an explicit run has no rejection: watch the error variable). ``failel`` (element
deletion) is never touched.

For implicit runs the same source holds the tangent routine (dyn21utan.f):
``utan4N(cm, eps, sig, epsp, hsv, dt1, unsym, capa, etype, tt, temper, es, crv, nnpcrv, failel,
cma, qmat)``. ``es(6,6)`` is the spatial tangent c / J, the push-forward of dS/dE divided by J (the
Truesdell rate of the Kirchhoff stress over J, without the Jaumann stress terms of Abaqus's
DDSDDE), rows and columns xx, yy, zz, xy, yz, zx, shear columns for engineering shear strain;
with a Prony series the consistent tangent of the step dt1 (the isochoric part times gamma_inf +
sum gain_i, as the UMAT's). ``unsym = .false.``: es is symmetric. It is computed from F
(``hsv(NHV+1 .. NHV+9)``), ``dt1`` and ``cm`` only (the tangent does not depend on the Prony
history). An error (constants invalid, element type, J <= 0, overflow) leaves ``es`` zero and
writes a line to unit 6; umat4N reports the same error for the step through ``reject``.
"""

from __future__ import annotations

import math
import re

from ..material.prony import GAMMA_INF_MIN
from .kernel import GAMMA_INF_FLOOR

UMAT41 = """\
      subroutine umat{N}(cm, eps, sig, epsp, hsv, dt1, capa, etype, tt,
     &  temper, failel, crv, nnpcrv, cma, qmat, elsiz, idele, reject)
      implicit none
{DP}
      real(dp), intent(in) :: cm(*), eps(6), dt1, capa, tt, temper
      real(dp), intent(inout) :: sig(6), epsp, hsv(*)
      character(len=5), intent(in) :: etype
      logical, intent(inout) :: failel, reject
      real(dp), intent(in) :: crv(*), cma(*), qmat(3,3), elsiz
      integer, intent(in) :: nnpcrv(*), idele
      real(dp) :: pv({NK}), gam({NPD}), tau({NPD}), hnew({NHD})
      real(dp) :: f(3,3), s(3,3), w(3,3), em(3), q(3,3), gt(3), ht(6)
      real(dp) :: xj, sse
      integer :: ierr, k
      integer, parameter :: nhv = {NS}
      integer, parameter :: ia(6) = [1, 2, 3, 1, 2, 3]
      integer, parameter :: ja(6) = [1, 2, 3, 2, 3, 1]
!     arguments this material does not use, referenced once so that
!     compilers do not warn about them
      if (.false.) then
        epsp = eps(1) + capa + temper + crv(1) + cma(1) + qmat(1,1)
     &    + elsiz + dble(nnpcrv(1) + idele)
        failel = .false.
      end if
      call {P}dynaf(cm, hsv, etype, pv, gam, tau, f, xj, ierr)
      if (ierr .eq. 0) then
        call {P}point(matmul(transpose(f), f), dt1, hsv(1:{NHD}), pv,
     &    gam, tau, .false., s, hnew, sse, em, q, gt, ht, ierr)
      end if
      if (ierr .ne. 0) then
        hsv(nhv) = dble(ierr)
        reject = .true.
        write (6, '(a,a,i2,a,es12.4,a)') ' umat{N} {NAME}: ', 'error ',
     &    ierr, ' at time ', tt,
     &    ' (see the error codes in the file header; is NHV = {NS}?)'
        return
      end if
      w = matmul(matmul(f, s), transpose(f)) / xj
      do k = 1, 6
        sig(k) = w(ia(k),ja(k))
      end do
      hsv(1:{NH}) = hnew(1:{NH})
      hsv(nhv) = 0.0d0
      end subroutine umat{N}
"""

UTAN41 = """\
      subroutine utan{N}(cm, eps, sig, epsp, hsv, dt1, unsym, capa,
     &  etype, tt, temper, es, crv, nnpcrv, failel, cma, qmat)
!     implicit tangent: es = c / J in the order xx, yy, zz, xy, yz, zx
      implicit none
{DP}
      real(dp), intent(in) :: cm(*), eps(6), sig(6), epsp, hsv(*)
      real(dp), intent(in) :: dt1, capa, tt, temper
      logical, intent(inout) :: unsym, failel
      character(len=5), intent(in) :: etype
      real(dp), intent(inout) :: es(6,*)
      real(dp), intent(in) :: crv(*), cma(*), qmat(3,3)
      integer, intent(in) :: nnpcrv(*)
      logical, external :: {P}finite
      real(dp) :: pv({NK}), gam({NPD}), tau({NPD}), hnew({NHD})
      real(dp) :: h0({NHD}), f(3,3), s(3,3), z(3,3), em(3), q(3,3)
      real(dp) :: gt(3), ht(6), dd(6,6), xj, sse
      integer :: ierr
      integer, parameter :: ia(6) = [1, 2, 3, 1, 2, 3]
      integer, parameter :: ja(6) = [1, 2, 3, 2, 3, 1]
      unsym = .false.
      es(1:6,1:6) = 0.0d0
!     arguments this material does not use, referenced once so that
!     compilers do not warn about them
      if (.false.) then
        xj = eps(1) + sig(1) + epsp + capa + temper + crv(1) + cma(1)
     &    + qmat(1,1) + dble(nnpcrv(1))
        failel = .false.
      end if
      call {P}dynaf(cm, hsv, etype, pv, gam, tau, f, xj, ierr)
      if (ierr .eq. 0) then
!       the tangent does not depend on the history: a zero one
        h0 = 0.0d0
        call {P}point(matmul(transpose(f), f), dt1, h0, pv, gam, tau,
     &    .true., s, hnew, sse, em, q, gt, ht, ierr)
      end if
      if (ierr .eq. 0) then
        z = 0.0d0
        call {P}cmj(f, xj, z, em, q, gt, ht, .false., ia, ja, dd)
        if (.not. {P}finite(dd, 36)) ierr = 2
      end if
      if (ierr .ne. 0) then
        write (6, '(a,a,i2,a,es12.4,a)') ' utan{N} {NAME}: ', 'error ',
     &    ierr, ' at time ', tt,
     &    ' (see the error codes in the file header); es = 0'
        return
      end if
      es(1:6,1:6) = dd
      end subroutine utan{N}

      subroutine {P}dynaf(cm, hsv, etype, pv, gam, tau, f, xj, ierr)
!     what umat{N} and utan{N} read from a call: the constants, and F
!     from hsv(NHV+1 .. NHV+9) column-major with J = det F; ierr 4 for
!     an element other than solid / sph, 1 for J <= 0, the constants'
!     own codes from {P}params
      implicit none
{DP}
      real(dp), intent(in) :: cm(*), hsv(*)
      character(len=5), intent(in) :: etype
      real(dp), intent(out) :: pv({NK}), gam({NPD}), tau({NPD})
      real(dp), intent(out) :: f(3,3), xj
      integer, intent(out) :: ierr
      real(dp), external :: {P}det3
      integer :: j, k
      integer, parameter :: nhv = {NS}
      ierr = 0
      pv = 0.0d0
      gam = 0.0d0
      tau = 1.0d0
      if (etype .ne. 'solid' .and. etype .ne. 'sph') then
        ierr = 4
      else
        call {P}params(cm(1:{NC}), pv, gam, tau, ierr)
      end if
      do j = 1, 3
        do k = 1, 3
          f(k,j) = hsv(nhv + k + 3 * (j - 1))
        end do
      end do
      xj = {P}det3(f)
      if (ierr .eq. 0 .and. .not. xj .gt. 0.0d0) ierr = 1
      end subroutine {P}dynaf
"""


def card(name: str, entries, nstate: int, density: float, number: int) -> str:
    """``*MAT_USER_DEFINED_MATERIAL_MODELS`` keyword block (LS-DYNA, SI units).

    Parameters
    ----------
    name : str
        Material name (title line).
    entries : list of Entry
        The constants with example values, the last two the bulk and shear modulus (``IBULK``,
        ``IG`` point at them).
    nstate : int
        ``NHV``: user history variables (the deformation gradient follows them).
    density : float
        ``RO`` (kg/m^3).
    number : int
        ``MT``, the user material number 41..50.

    Returns
    -------
    str
        Keyword text: comment lines (the routines, the constants), title, card 1 (MID, RO, MT, LMC,
        NHV, IORTHO, IBULK, IG), card 2 (IVECT, IFAIL, ITHERM, IHYPER = 1, IEOS), then the constants
        8 per line in fields of 10.
    """
    n = len(entries)
    lines = [f"$ material '{name}' for the generated umat{number} (SI units: m, s, kg, Pa); double-precision LS-DYNA",
             f"$ implicit runs: the same source has utan{number}, the tangent (es = c/J, symmetric)",
             "$ both verified through the calling convention by cfm's harness only, not run in LS-DYNA here"]
    lines += [f"$   cm({i:>2}) {e.name:<8} [{e.unit}] {e.meaning}" for i, e in enumerate(entries, 1)]
    lines += ["*MAT_USER_DEFINED_MATERIAL_MODELS_TITLE", name,
              "$      MID        RO        MT       LMC       NHV    IORTHO     IBULK        IG",
              "".join(f"{v:>10}" for v in (1, _field(density).strip(), number, n, nstate, 0, n - 1, n)),
              "$    IVECT     IFAIL    ITHERM    IHYPER      IEOS",
              "".join(f"{v:>10}" for v in (0, 0, 0, 1, 0)),
              "$ constants P1 .. P%d" % n]
    values = [_field(e.default) for e in entries]
    lines += [f"$ rounded to the 10-character fields: {text}" for text in rounded(entries)]
    lines += ["".join(values[i:i + 8]) for i in range(0, n, 8)]
    return "\n".join(lines) + "\n"


def _field(value: float) -> str:
    """A value in a 10-character field of LS-DYNA's fixed format, as exact as the field allows: the
    shortest text that reads back to the same float, else the most significant digits that fit, in
    plain or compact exponent form (``1.2345679e-7``: no exponent padding). A 9-character limit with
    Python's padded exponent kept 4 digits of 1.23456789e-7, and 7 of 0.47099966, which left the Prony
    series a gamma_inf 12 % off (below cfm's floor of 1e-6)."""
    text = repr(float(value))
    if len(text) <= FIELD:
        return f"{text:>{FIELD}}"
    best = f"{value:.1e}"
    for digits in range(FIELD, 0, -1):
        plain = f"{value:.{digits}g}"
        mantissa, _, exponent = f"{value:.{digits - 1}e}".partition("e")
        compact = f"{mantissa}e{int(exponent)}"
        fits = [t for t in (plain, compact) if len(t) <= FIELD]
        if fits:
            best = min(fits, key=lambda t: abs(float(t) - value))
            break
    return f"{best:>{FIELD}}"


#: Characters of a field of LS-DYNA's fixed-format cards.
FIELD = 10


def rounded(entries) -> list[str]:
    """The constants a card's 10-character fields change by more than 1e-9 relative (:func:`_field`), one
    text each: name, the value, what the field holds and the relative change; then gamma_inf = 1 -
    sum g_i if the written g_i change it by more than 1e-9 relative (:func:`gamma_inf_on_card`)."""
    out = []
    for e in entries:
        v = float(e.default)
        held = float(_field(v))
        if abs(held - v) > 1e-9 * abs(v):
            out.append(f"{e.name} = {v!r} is written {held!r} (relative change {abs(held - v) / abs(v):.1g})")
    exact, held = gamma_inf_on_card(entries)
    if exact is not None and abs(held - exact) > 1e-9 * abs(exact):
        out.append(f"gamma_inf = 1 - sum g_i = {exact:.6g} is {held:.6g} from the written g_i (relative change "
                   f"{abs(held - exact) / abs(exact):.1g}; moduli scale by it)")
    return out


#: Relative change of gamma_inf by the card's rounding above which ``cfm export`` warns.
GAMMA_INF_CHANGE_WARN = 1e-3


def gamma_inf_on_card(entries) -> tuple:
    """(gamma_inf of the constants, gamma_inf of the card's 10-character fields) = 1 - sum of the
    Prony coefficients g1, g2, ... (summed exactly, ``math.fsum``; (None, None) without them).
    Each field keeps ~8 significant digits, so each g_i moves by up to ~5e-9; near cfm's floor of
    gamma_inf = 1e-6 that moves gamma_inf, and the moduli it scales (1 / gamma_inf for long-term
    constants), by up to ~1.5 % though every g_i changed by only 1e-8 relative."""
    g = [e for e in entries if re.fullmatch(r"g\d+", e.name)]
    if not g:
        return None, None
    return (math.fsum([1.0] + [-float(e.default) for e in g]),
            math.fsum([1.0] + [-float(_field(float(e.default))) for e in g]))


def gamma_inf_warning(entries) -> str | None:
    """The warning ``cfm export`` gives when the card's rounding moves gamma_inf by more than
    :data:`GAMMA_INF_CHANGE_WARN` relative (:func:`gamma_inf_on_card`), saying also when the card's value
    falls below what the routine accepts (:data:`cfm_core.export.kernel.GAMMA_INF_FLOOR`); None otherwise."""
    exact, held = gamma_inf_on_card(entries)
    if exact is None or not abs(held - exact) > GAMMA_INF_CHANGE_WARN * exact:
        return None
    below = (f" On the card it is below the floor the routine accepts ({GAMMA_INF_MIN:g}): every call would "
             f"end with error code 3 (invalid constants); raise gamma_inf (lower a g_i)." if held < GAMMA_INF_FLOOR else "")
    return (f"the card's 10-character fields round the Prony coefficients g_i so that gamma_inf = 1 - sum g_i is "
            f"{held:.6g} on the card for {exact:.6g} (relative change {abs(held - exact) / exact:.1g}): LS-DYNA's "
            f"long-term or relaxed stresses differ by as much. Near gamma_inf = 0 no 10-character field can do "
            f"better; the exact values are in manifest.json.{below}")
