"""The solver-independent core of every generated user material (fixed-form Fortran text).

Formulae of the numpy reference (:mod:`cfm_core.material.reference`, :mod:`~cfm_core.material.kinematics`,
:mod:`~cfm_core.material.prony`), written once in Fortran:

- ``<p>eig3``: eigenvalues and eigenvectors of the symmetric C by cyclic Jacobi rotations; a
  diagonal C (the reference state, uniaxial states) is returned exactly with Q = I, and repeated
  eigenvalues need no special case: the stress is assembled as sum_a 2 psi_a N_a (x) N_a, which
  eigenvector errors between equal eigenvalues do not change.
- ``<p>params``: constants -> energy parameters, s_iso (1 / gamma_inf for long-term moduli),
  gamma_i, tau_i; error 3 when a constant is outside its declared range or gamma_inf = 1 - sum
  gamma_i is below the floor cfm itself refuses (:data:`cfm_core.material.prony.GAMMA_INF_MIN`, less
  1e-12 for the round-off of the Fortran sum): a card edited to such values would otherwise run at
  moduli up to 1 / gamma_inf times the intended ones.
- ``<p>point``: one step at a material point: instantaneous isochoric and volumetric second
  Piola-Kirchhoff stress from the generated derivatives, the Prony recurrence on the isochoric
  part with the exact exponential factors (docs/conventions.md section 2), the total S, the new
  history; with ``wantt`` also the principal derivatives of the consistent tangent (isochoric
  part times gamma_inf + sum gain_i).
- ``<p>cmj``: the spatial tangent c / J = J^-1 F F F F : CC (the Truesdell rate of the Kirchhoff
  stress divided by J: LS-DYNA's ``utan`` es) or, with ``jaum``, the Jaumann-rate tangent (Abaqus's
  DDSDDE): that plus 1/2 (d_ik s_jl + d_il s_jk + d_jk s_il + d_jl s_ik); rows and columns in the
  component order the caller passes (``ia``, ``ja``), shear columns for engineering shear strain.
"""

from __future__ import annotations

from ..material.prony import GAMMA_INF_MIN

#: The smallest gamma_inf = 1 - sum g_i the generated routines accept (error code 3 below it): cfm's own
#: floor less 1e-12 for the round-off of the Fortran sum, so that every value cfm accepts runs.
GAMMA_INF_FLOOR = GAMMA_INF_MIN - 1e-12

CORE = """\
      subroutine {P}eig3(a, em, q)
!     eigenvalues em and eigenvectors q (columns) of the symmetric a
      implicit none
{DP}
      real(dp), intent(in) :: a(3,3)
      real(dp), intent(out) :: em(3), q(3,3)
      real(dp) :: b(3,3), th, t, c, s, x, y, off, dia
      integer :: sweep, ip, iq, k, n
      integer, parameter :: pp(3) = [1, 1, 2], qq(3) = [2, 3, 3]
      b = a
      q = 0.0d0
      do k = 1, 3
        q(k,k) = 1.0d0
      end do
      do sweep = 1, 50
        off = abs(b(1,2)) + abs(b(1,3)) + abs(b(2,3))
        dia = abs(b(1,1)) + abs(b(2,2)) + abs(b(3,3))
        if (off .le. 1.0d-18 * dia .or. off .eq. 0.0d0) exit
        do n = 1, 3
          ip = pp(n)
          iq = qq(n)
          if (b(ip,iq) .eq. 0.0d0) cycle
          th = (b(iq,iq) - b(ip,ip)) / (2.0d0 * b(ip,iq))
          if (abs(th) .gt. 1.0d150) then
            t = 0.5d0 / th
          else
            t = sign(1.0d0 / (abs(th) + sqrt(th * th + 1.0d0)), th)
          end if
          c = 1.0d0 / sqrt(t * t + 1.0d0)
          s = t * c
          do k = 1, 3
            x = b(k,ip)
            y = b(k,iq)
            b(k,ip) = c * x - s * y
            b(k,iq) = s * x + c * y
          end do
          do k = 1, 3
            x = b(ip,k)
            y = b(iq,k)
            b(ip,k) = c * x - s * y
            b(iq,k) = s * x + c * y
          end do
          b(ip,iq) = 0.0d0
          b(iq,ip) = 0.0d0
          do k = 1, 3
            x = q(k,ip)
            y = q(k,iq)
            q(k,ip) = c * x - s * y
            q(k,iq) = s * x + c * y
          end do
        end do
      end do
      do k = 1, 3
        em(k) = b(k,k)
      end do
      end subroutine {P}eig3

      logical function {P}finite(x, n)
      use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
      implicit none
{DP}
      integer, intent(in) :: n
      real(dp), intent(in) :: x(n)
      {P}finite = all(ieee_is_finite(x))
      end function {P}finite

      function {P}det3(a) result(d)
      implicit none
{DP}
      real(dp), intent(in) :: a(3,3)
      real(dp) :: d
      d = a(1,1) * (a(2,2) * a(3,3) - a(2,3) * a(3,2))
     &  - a(1,2) * (a(2,1) * a(3,3) - a(2,3) * a(3,1))
     &  + a(1,3) * (a(2,1) * a(3,2) - a(2,2) * a(3,1))
      end function {P}det3

      subroutine {P}params(props, pv, gam, tau, ierr)
!     constants -> energy parameters pv (then s_iso), gamma_i, tau_i
      implicit none
{DP}
      real(dp), intent(in) :: props({NC})
      real(dp), intent(out) :: pv({NK}), gam({NPD}), tau({NPD})
      integer, intent(out) :: ierr
      logical, external :: {P}badprops
      real(dp) :: ginf
      integer :: i
      ierr = 0
      gam = 0.0d0
      tau = 1.0d0
      do i = 1, {NK} - 1
        pv(i) = props(i)
      end do
!prony{
      do i = 1, {NP}
        gam(i) = props({NK} - 1 + 2 * i - 1)
        tau(i) = props({NK} - 1 + 2 * i)
      end do
!}prony
      ginf = 1.0d0 - sum(gam)
      pv({NK}) = 1.0d0
      if (.false.) pv({NK}) = tau(1)
!     gamma_inf below cfm's floor (1 - sum has ~1e-16 of round-off)
      if ({P}badprops(props) .or. .not. ginf .ge. {GMIN}) then
        ierr = 3
      else if (props({NC}) .eq. 1.0d0) then
        pv({NK}) = 1.0d0 / ginf
      end if
      end subroutine {P}params

      subroutine {P}factors(dt, gam, tau, decay, gain)
!     exact recurrence: exp(-dt/tau), gam tau/dt (1 - exp(-dt/tau))
      implicit none
{DP}
      real(dp), intent(in) :: dt, gam, tau
      real(dp), intent(out) :: decay, gain
      real(dp) :: x
      if (dt .le. 0.0d0) then
        decay = 1.0d0
        gain = gam
        return
      end if
      x = dt / tau
      decay = exp(-x)
      if (x .lt. 1.0d-2) then
        gain = gam * (1.0d0 - x / 2.0d0 * (1.0d0 - x / 3.0d0
     &       * (1.0d0 - x / 4.0d0 * (1.0d0 - x / 5.0d0
     &       * (1.0d0 - x / 6.0d0)))))
      else
        gain = gam * (1.0d0 - decay) / x
      end if
      end subroutine {P}factors

      subroutine {P}point(cc, dt, hold, pv, gam, tau,
     &  wantt, s, hnew, sse, em, q, gt, ht, ierr)
!     one step at a point: C, dt, history -> total S, new history
      implicit none
{DP}
      real(dp), intent(in) :: cc(3,3), dt, hold({NHD}), pv({NK})
      real(dp), intent(in) :: gam({NPD}), tau({NPD})
      logical, intent(in) :: wantt
      real(dp), intent(out) :: s(3,3), hnew({NHD}), sse, em(3)
      real(dp), intent(out) :: q(3,3), gt(3), ht(6)
      integer, intent(out) :: ierr
      logical, external :: {P}finite
      real(dp) :: e(2), g(6), h(12), s0(6), sv(6), st(6)
      real(dp) :: f, ginf
      integer :: k, a
!prony{
      real(dp) :: decay, gain
      integer :: i, o
!}prony
      integer, parameter :: iv(6) = [1, 2, 3, 1, 2, 1]
      integer, parameter :: jv(6) = [1, 2, 3, 2, 3, 3]
      ierr = 0
      s = 0.0d0
      hnew = hold
      sse = 0.0d0
      gt = 0.0d0
      ht = 0.0d0
      call {P}eig3(cc, em, q)
      if (.not. minval(em) .gt. 0.0d0) then
        ierr = 1
        return
      end if
      h = 0.0d0
      if (wantt) then
        call {P}psih(em, pv, e, g, h)
      else
        call {P}psi(em, pv, e, g)
      end if
      if (.not. {P}finite(e, 2)) ierr = 2
      if (.not. {P}finite(g, 6)) ierr = 2
      if (.not. {P}finite(h, 12)) ierr = 2
      if (ierr .ne. 0) return
      do k = 1, 6
        s0(k) = 0.0d0
        sv(k) = 0.0d0
        do a = 1, 3
          s0(k) = s0(k) + 2.0d0 * g(a) * q(iv(k),a) * q(jv(k),a)
          sv(k) = sv(k) + 2.0d0 * g(3+a) * q(iv(k),a) * q(jv(k),a)
        end do
      end do
      ginf = 1.0d0 - sum(gam)
      f = 1.0d0
      st = s0
!prony{
      if ({NP} .gt. 0) then
        f = ginf
        st = ginf * s0
        o = 6 * {NP}
        do i = 1, {NP}
          call {P}factors(dt, gam(i), tau(i), decay, gain)
          do k = 1, 6
            hnew(6*(i-1)+k) = decay * hold(6*(i-1)+k)
     &                      + gain * (s0(k) - hold(o+k))
            st(k) = st(k) + hnew(6*(i-1)+k)
          end do
          f = f + gain
        end do
        do k = 1, 6
          hnew(o+k) = s0(k)
        end do
      end if
!}prony
!noprony{
      if (.false.) f = dt + tau(1)
!}noprony
      sse = ginf * e(1) + e(2)
      do k = 1, 6
        s(iv(k),jv(k)) = st(k) + sv(k)
        s(jv(k),iv(k)) = st(k) + sv(k)
      end do
      if (wantt) then
        do a = 1, 3
          gt(a) = f * g(a) + g(3+a)
        end do
        do k = 1, 6
          ht(k) = f * h(k) + h(6+k)
        end do
      end if
      if (.not. {P}finite(s, 9)) ierr = 2
      if (.not. {P}finite(hnew, {NHD})) ierr = 2
      end subroutine {P}point
"""

TANGENT = """\
      subroutine {P}cmj(f, xj, sig, em, q, gt, ht,
     &  jaum, ia, ja, dd)
!     spatial tangent c / J (push-forward of dS/dE over J: the
!     Truesdell rate of Kirchhoff stress / J, LS-DYNA's utan es); with
!     jaum the Jaumann rate instead (plus the stress term: Abaqus's
!     DDSDDE); component k of rows and columns is (ia(k), ja(k))
      implicit none
{DP}
      real(dp), intent(in) :: f(3,3), xj, sig(3,3), em(3), q(3,3)
      real(dp), intent(in) :: gt(3), ht(6)
      logical, intent(in) :: jaum
      integer, intent(in) :: ia(6), ja(6)
      real(dp), intent(out) :: dd(6,6)
      real(dp) :: v(3,3), hm(3,3), th(3,3), d(3,3), c, dm
      integer :: a, b, i, j, k, l, ka, kb, n
      integer, parameter :: pa(3) = [1, 2, 1], pb(3) = [2, 3, 3]
      v = matmul(f, q)
      d = 0.0d0
      do a = 1, 3
        d(a,a) = 1.0d0
        hm(a,a) = ht(a)
      end do
      th = 0.0d0
      do n = 1, 3
        a = pa(n)
        b = pb(n)
        hm(a,b) = ht(3+n)
        hm(b,a) = ht(3+n)
        dm = em(a) - em(b)
        if (abs(dm) .le. 1.0d-4 * max(abs(em(a)), abs(em(b)))) then
          th(a,b) = 0.5d0 * (ht(a) + ht(b)) - ht(3+n)
        else
          th(a,b) = (gt(a) - gt(b)) / dm
        end if
        th(b,a) = th(a,b)
      end do
      do ka = 1, 6
        i = ia(ka)
        j = ja(ka)
        do kb = 1, 6
          k = ia(kb)
          l = ja(kb)
          c = 0.0d0
          do a = 1, 3
            do b = 1, 3
              c = c + 4.0d0 * hm(a,b) * v(i,a) * v(j,a) * v(k,b)
     &          * v(l,b)
              if (a .ne. b) then
                c = c + 2.0d0 * th(a,b) * v(i,a) * v(j,b)
     &            * (v(k,a) * v(l,b) + v(k,b) * v(l,a))
              end if
            end do
          end do
          dd(ka,kb) = c / xj
          if (jaum) then
            dd(ka,kb) = dd(ka,kb) + 0.5d0 * (d(i,k) * sig(j,l)
     &        + d(i,l) * sig(j,k) + d(j,k) * sig(i,l)
     &        + d(j,l) * sig(i,k))
          end if
        end do
      end do
      end subroutine {P}cmj
"""


def core_source(prefix: str, sizes: dict, tangent: bool) -> str:
    """The core routines with the material's prefix and sizes filled in.

    Parameters
    ----------
    prefix : str
        Name prefix of the generated routines.
    sizes : dict
        ``NC`` constants, ``NK`` energy parameters + 1 (s_iso), ``NP`` Prony terms, ``NPD`` =
        max(NP, 1), ``NHD`` = max(6 (NP + 1), 1) history length; ``DP`` the kind line.
    tangent : bool
        Include ``<p>cmj`` (the UMAT's DDSDDE, LS-DYNA's utan41 es).

    Returns
    -------
    str
        Fixed-form Fortran source.
    """
    text = CORE + ("\n" + TANGENT if tangent else "")
    text = _prony_blocks(text, sizes["NP"] > 0)
    for key, value in {**sizes, "P": prefix}.items():
        text = text.replace("{" + key + "}", str(value))
    return text


def _prony_blocks(text: str, keep: bool) -> str:
    """Drop the lines between ``!prony{`` and ``!}prony`` for a material without a Prony series
    (so that no zero-trip loop is compiled); always drop the marker lines."""
    out, skip = [], False
    for line in text.split("\n"):
        if line.strip() in ("!prony{", "!noprony{"):
            skip = keep == (line.strip() == "!noprony{")
        elif line.strip() in ("!}prony", "!}noprony"):
            skip = False
        elif not skip:
            out.append(line)
    return "\n".join(out)
