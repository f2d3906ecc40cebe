"""Abaqus interfaces: the UMAT (Abaqus/Standard, CalculiX) and the VUMAT (Abaqus/Explicit).

Calling conventions as the Abaqus User Subroutines Reference Guide writes them
(docs/conventions.md section 7):

- UMAT: ``DFGRD1`` column-major, ``STRESS`` the Cauchy stress in the order 11, 22, 33, 12, 13, 23,
  ``DDSDDE`` the Jaumann-rate tangent of Kirchhoff stress / J with engineering shear strains,
  ``SSE`` the long-term elastic energy (gamma_inf psi_iso + psi_vol) and ``SCD`` the work done
  minus SSE (energy held in and dissipated by the Prony branches), both per unit reference
  volume. An error (J <= 0, overflow, invalid constants) sets ``PNEWDT = 0.25`` (Abaqus cuts the
  increment back), leaves STRESS and the history unchanged, writes the code into the last state
  variable and a line to unit 6.
- VUMAT: vectorised over ``nblock``; the stress is the corotational sigma_hat = R^T sigma R =
  J^-1 U S(U^2) U computed from ``stretchNew`` (F = R U), order 11, 22, 33, 12, 23, 31;
  ``enerInternNew`` the specific internal energy (stress power / density, trapezoidal). An error
  keeps the old stress and state of that point, writes the code into its last state variable and
  a line to unit 6 (Abaqus/Explicit has no increment cutback).
"""

from __future__ import annotations

UMAT = """\
      subroutine umat(stress, statev, ddsdde, sse, spd, scd, rpl,
     &  ddsddt, drplde, drpldt, stran, dstran, time, dtime, temp,
     &  dtemp, predef, dpred, cmname, ndi, nshr, ntens, nstatv, props,
     &  nprops, coords, drot, pnewdt, celent, dfgrd0, dfgrd1, noel,
     &  npt, layer, kspt, kstep, kinc)
      implicit none
{DP}
      character(len=80), intent(in) :: cmname
      integer, intent(in) :: ndi, nshr, ntens, nstatv, nprops
      integer, intent(in) :: noel, npt, layer, kspt, kstep, kinc
      real(dp), intent(inout) :: stress(ntens), statev(nstatv)
      real(dp), intent(inout) :: ddsdde(ntens,ntens), sse, spd, scd
      real(dp), intent(inout) :: rpl, ddsddt(ntens), drplde(ntens)
      real(dp), intent(inout) :: drpldt, pnewdt
      real(dp), intent(in) :: stran(ntens), dstran(ntens), time(2)
      real(dp), intent(in) :: dtime, temp, dtemp, predef(*), dpred(*)
      real(dp), intent(in) :: props(nprops), coords(3), drot(3,3)
      real(dp), intent(in) :: celent, dfgrd0(3,3), dfgrd1(3,3)
      real(dp), external :: {P}det3
      real(dp) :: pv({NK}), gam({NPD}), tau({NPD}), hnew({NHD})
      real(dp) :: s(3,3), sig(3,3), em(3), q(3,3), gt(3), ht(6)
      real(dp) :: xj, xj0, sold(3,3), f0i(3,3), work, de(3,3), sse1
      real(dp) :: dd(6,6)
      integer :: ierr, k
      integer, parameter :: ia(6) = [1, 2, 3, 1, 1, 2]
      integer, parameter :: ja(6) = [1, 2, 3, 2, 3, 3]
      ierr = 0
      rpl = 0.0d0
      ddsddt = 0.0d0
      drplde = 0.0d0
      drpldt = 0.0d0
!     arguments this material does not use, referenced once so that
!     compilers do not warn about them
      if (.false.) then
        spd = celent + coords(1) + drot(1,1) + temp + dtemp + predef(1)
     &    + dpred(1) + stran(1) + dstran(1) + time(1)
     &    + dble(layer + kspt + kstep + kinc + len(cmname))
      end if
      if (ndi .ne. 3 .or. nshr .ne. 3) then
        ierr = 4
      else if (nprops .ne. {NC} .or. nstatv .lt. {NS}) then
        ierr = 3
      else
        call {P}params(props, pv, gam, tau, ierr)
      end if
      xj = {P}det3(dfgrd1)
      if (ierr .eq. 0 .and. .not. xj .gt. 0.0d0) ierr = 1
      if (ierr .eq. 0) then
        call {P}point(matmul(transpose(dfgrd1), dfgrd1), dtime,
     &    statev(1:{NHD}), pv, gam, tau, .true., s, hnew, sse1, em, q,
     &    gt, ht, ierr)
      end if
      if (ierr .ne. 0) then
        pnewdt = min(pnewdt, 0.25d0)
        if (nstatv .ge. {NS}) statev({NS}) = dble(ierr)
        write (6, '(a,a,i2,a,i0,a,i0,a)') ' umat {NAME}: ',
     &    'error ', ierr, ' at element ', noel, ' point ', npt,
     &    ' (see the error codes in the file header); PNEWDT = 0.25'
        return
      end if
      sig = matmul(matmul(dfgrd1, s), transpose(dfgrd1)) / xj
!     work of the step per reference volume (trapezoidal in S : dE)
      xj0 = {P}det3(dfgrd0)
      call {P}inv3(dfgrd0, f0i)
      sold = 0.0d0
      do k = 1, 6
        sold(ia(k),ja(k)) = stress(k)
        sold(ja(k),ia(k)) = stress(k)
      end do
      sold = xj0 * matmul(matmul(f0i, sold), transpose(f0i))
      de = 0.5d0 * (matmul(transpose(dfgrd1), dfgrd1)
     &   - matmul(transpose(dfgrd0), dfgrd0))
      work = 0.5d0 * sum((sold + s) * de)
      scd = scd + work - (sse1 - sse)
      sse = sse1
      do k = 1, 6
        stress(k) = sig(ia(k),ja(k))
      end do
      call {P}cmj(dfgrd1, xj, sig, em, q, gt, ht,
     &  .true., ia, ja, dd)
      ddsdde(1:6,1:6) = dd
      statev(1:{NH}) = hnew(1:{NH})
      statev({NS}) = 0.0d0
      end subroutine umat

      subroutine {P}inv3(a, b)
      implicit none
{DP}
      real(dp), intent(in) :: a(3,3)
      real(dp), intent(out) :: b(3,3)
      real(dp), external :: {P}det3
      b(1,1) = a(2,2) * a(3,3) - a(2,3) * a(3,2)
      b(1,2) = a(1,3) * a(3,2) - a(1,2) * a(3,3)
      b(1,3) = a(1,2) * a(2,3) - a(1,3) * a(2,2)
      b(2,1) = a(2,3) * a(3,1) - a(2,1) * a(3,3)
      b(2,2) = a(1,1) * a(3,3) - a(1,3) * a(3,1)
      b(2,3) = a(1,3) * a(2,1) - a(1,1) * a(2,3)
      b(3,1) = a(2,1) * a(3,2) - a(2,2) * a(3,1)
      b(3,2) = a(1,2) * a(3,1) - a(1,1) * a(3,2)
      b(3,3) = a(1,1) * a(2,2) - a(1,2) * a(2,1)
      b = b / {P}det3(a)
      end subroutine {P}inv3
"""

VUMAT = """\
      subroutine vumat(nblock, ndir, nshr, nstatev, nfieldv, nprops,
     &  lanneal, steptime, totaltime, dt, cmname, coordmp, charlength,
     &  props, density, straininc, relspininc, tempold, stretchold,
     &  defgradold, fieldold, stressold, stateold, enerinternold,
     &  enerinelasold, tempnew, stretchnew, defgradnew, fieldnew,
     &  stressnew, statenew, enerinternnew, enerinelasnew)
      implicit none
{DP}
      integer, intent(in) :: nblock, ndir, nshr, nstatev, nfieldv
      integer, intent(in) :: nprops, lanneal
      real(dp), intent(in) :: steptime, totaltime, dt
      character(len=80), intent(in) :: cmname
      real(dp), intent(in) :: coordmp(nblock,*), charlength(nblock)
      real(dp), intent(in) :: props(nprops), density(nblock)
      real(dp), intent(in) :: straininc(nblock,ndir+nshr)
      real(dp), intent(in) :: relspininc(nblock,nshr), tempold(nblock)
      real(dp), intent(in) :: stretchold(nblock,ndir+nshr)
      real(dp), intent(in) :: defgradold(nblock,ndir+nshr+nshr)
      real(dp), intent(in) :: fieldold(nblock,nfieldv)
      real(dp), intent(in) :: stressold(nblock,ndir+nshr)
      real(dp), intent(in) :: stateold(nblock,nstatev)
      real(dp), intent(in) :: enerinternold(nblock)
      real(dp), intent(in) :: enerinelasold(nblock), tempnew(nblock)
      real(dp), intent(in) :: stretchnew(nblock,ndir+nshr)
      real(dp), intent(in) :: defgradnew(nblock,ndir+nshr+nshr)
      real(dp), intent(in) :: fieldnew(nblock,nfieldv)
      real(dp), intent(out) :: stressnew(nblock,ndir+nshr)
      real(dp), intent(out) :: statenew(nblock,nstatev)
      real(dp), intent(out) :: enerinternnew(nblock)
      real(dp), intent(out) :: enerinelasnew(nblock)
      real(dp), external :: {P}det3
      real(dp) :: pv({NK}), gam({NPD}), tau({NPD}), hnew({NHD})
      real(dp) :: u(3,3), s(3,3), sig(3,3), em(3), q(3,3), gt(3)
      real(dp) :: ht(6), xj, sse, power
      integer :: ierr, ierr0, km, k
      integer, parameter :: ia(6) = [1, 2, 3, 1, 2, 3]
      integer, parameter :: ja(6) = [1, 2, 3, 2, 3, 1]
      ierr0 = 0
!     arguments this material does not use, referenced once so that
!     compilers do not warn about them
      if (.false.) then
        stressnew(1,1) = steptime + totaltime + coordmp(1,1)
     &    + charlength(1) + relspininc(1,1) + tempold(1)
     &    + stretchold(1,1) + defgradold(1,1) + fieldold(1,1)
     &    + tempnew(1) + defgradnew(1,1) + fieldnew(1,1)
     &    + dble(lanneal + len(cmname))
      end if
      if (ndir .ne. 3 .or. nshr .ne. 3) then
        ierr0 = 4
      else if (nprops .ne. {NC} .or. nstatev .lt. {NS}) then
        ierr0 = 3
      else
        call {P}params(props, pv, gam, tau, ierr0)
      end if
      do km = 1, nblock
        ierr = ierr0
        if (ierr .eq. 0) then
          do k = 1, 6
            u(ia(k),ja(k)) = stretchnew(km,k)
            u(ja(k),ia(k)) = stretchnew(km,k)
          end do
          xj = {P}det3(u)
          if (.not. xj .gt. 0.0d0) ierr = 1
        end if
        if (ierr .eq. 0) then
          call {P}point(matmul(u, u), dt, stateold(km,1:{NHD}), pv,
     &      gam, tau, .false., s, hnew, sse, em, q, gt, ht, ierr)
        end if
        if (ierr .ne. 0) then
          stressnew(km,:) = stressold(km,:)
          statenew(km,:) = stateold(km,:)
          if (nstatev .ge. {NS}) statenew(km,{NS}) = dble(ierr)
          enerinternnew(km) = enerinternold(km)
          enerinelasnew(km) = enerinelasold(km)
          write (6, '(a,a,i2,a,i0,a)') ' vumat {NAME}: ', 'error ',
     &      ierr, ' at block point ', km,
     &      ' (see the error codes in the file header)'
          cycle
        end if
        sig = matmul(matmul(u, s), u) / xj
        power = 0.0d0
        do k = 1, 6
          stressnew(km,k) = sig(ia(k),ja(k))
          power = power + merge(1.0d0, 2.0d0, k .le. 3)
     &      * (stressold(km,k) + stressnew(km,k)) * straininc(km,k)
        end do
        enerinternnew(km) = enerinternold(km)
     &    + 0.5d0 * power / density(km)
        enerinelasnew(km) = enerinelasold(km)
        statenew(km,:) = stateold(km,:)
        statenew(km,1:{NH}) = hnew(1:{NH})
        statenew(km,{NS}) = 0.0d0
      end do
      end subroutine vumat
"""


def umat_card(name: str, entries, nstate: int) -> str:
    """Abaqus input-file material block for the UMAT (and CalculiX).

    Parameters
    ----------
    name : str
        Material name on ``*MATERIAL, NAME=``.
    entries : list of Entry
        The constants with their example values (:func:`cfm_core.export.layout.constants`).
    nstate : int
        Number of state variables (``*DEPVAR``).

    Returns
    -------
    str
        The block: ``*MATERIAL``, ``*USER MATERIAL, CONSTANTS=n`` with at most 8 values a line,
        ``*DEPVAR``, and comment lines naming each constant.
    """
    return _card(name, entries, nstate, explicit=False)


def vumat_card(name: str, entries, nstate: int, density: float) -> str:
    """Abaqus/Explicit material block for the VUMAT (adds ``*DENSITY``, which Explicit needs).

    Parameters
    ----------
    name : str
        Material name.
    entries : list of Entry
        The constants with their example values.
    nstate : int
        Number of state variables.
    density : float
        Mass density (kg/m^3) for ``*DENSITY``.

    Returns
    -------
    str
        The material block.
    """
    return _card(name, entries, nstate, explicit=True, density=density)


def _card(name, entries, nstate, explicit, density=None):
    lines = [f"** material '{name}' for the generated {'VUMAT' if explicit else 'UMAT'} (SI units: m, s, kg, Pa)"]
    lines += [f"**   constant {i:>2} {e.name:<8} [{e.unit}] {e.meaning}" for i, e in enumerate(entries, 1)]
    if not explicit:
        lines += ["** CalculiX: not a drop-in for stock ccx. 'cfm calculix build' links this UMAT into ccx with the",
                  "** adaptor its conventions need, for materials named ABAQUS... (the calculix backend's decks)"]
    lines.append(f"*MATERIAL, NAME={name.upper()}")
    if density is not None:
        lines += ["*DENSITY", repr(float(density))]
    lines.append(f"*USER MATERIAL, CONSTANTS={len(entries)}")
    values = [repr(float(e.default)) for e in entries]
    lines += [", ".join(values[i:i + 8]) for i in range(0, len(values), 8)]
    lines += ["*DEPVAR", str(nstate)]
    return "\n".join(lines) + "\n"
