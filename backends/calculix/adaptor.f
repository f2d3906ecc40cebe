!     cfm: CalculiX adaptor between ccx's ABAQUS user-material call
!     (umat_abaqus.f: PK2 stress in and out, the tangent dS/dE) and
!     the project's generated Abaqus UMATs (Cauchy stress, DDSDDE the
!     Jaumann-rate tangent of Kirchhoff stress / J, from DFGRD0/1).
!     The generated routines are renamed CFMU_<n>; the dispatch on the
!     material name (after the ABAQUS prefix) is generated with them
!     in place of the line CFM-DISPATCH. A material error of the UMAT
!     (its PNEWDT < 1: J <= 0, overflow) is passed to ccx as PNEWDT =
!     0.5 (ccx starts from -1) with the line 'CFM-UMAT-CUTBACK element
!     point time': ccx rejects the iterate and halves the increment,
!     or stops (fixed increments, minimum increment) with an error.
!     Not the UMAT's 0.25: ccx's contact rules let an increment grow
!     by 10 % per increment only, so each quarter cut cost ~15 small
!     increments in the drop test; a half cut costs ~7.
!     The 3x3 determinant and inverse (cfmad_det3, cfmad_inv3) are the
!     export's own routines, generated in place of the line CFM-HELPERS
!     from the same templates as the UMATs (build.py, adaptor_source).
      subroutine umat(stress,statev,ddsdde,sse,spd,scd,
     &  rpl,ddsddt,drplde,drpldt,
     &  stran,dstran,time,dtime,temp,dtemp,predef,dpred,cmname,
     &  ndi,nshr,ntens,nstatv,props,nprops,coords,drot,pnewdt,
     &  celent,dfgrd0,dfgrd1,noel,npt,layer,kspt,kstep,kinc)
      implicit none
      character*80 cmname
      integer ndi,nshr,ntens,nstatv,nprops,noel,npt,layer,kspt,
     &  kstep(4),kinc
      double precision stress(6),statev(*),ddsdde(6,6),sse,spd,scd,
     &  rpl,ddsddt(6),drplde(6),drpldt,stran(6),dstran(6),time(2),
     &  dtime,temp,dtemp,predef(*),dpred(*),props(*),coords(3),
     &  drot(3,3),pnewdt,celent,dfgrd0(3,3),dfgrd1(3,3)
      double precision sig(6),dd(6,6),f(3,3),fi(3,3),t(3,3),s(3,3),
     &  c4(3,3,3,3),tau(3,3),xj,xj0,pnew,e1,e2,e3,e4,e5,e6,e7,dtl
      logical first
      double precision cfmad_det3
      integer ia(6),ja(6),iv(3,3),a,b,i,j,k,l,p,q,r,m,found
      data ia /1,2,3,1,1,2/
      data ja /1,2,3,2,3,3/
      data iv /1,4,5,4,2,6,5,6,3/
!     *DYNAMIC's initial-acceleration call (total time -1, DTIME 1):
!     ccx integrates C3D8R there at 8 points and hands in states and
!     stresses it never initialised. The material starts undeformed
!     and unloaded: zero state and stress in, no time passing (DTIME
!     0), and the state left at zero for the first increment.
      first = time(2) .lt. 0.0d0
      dtl = dtime
      if (first) then
        statev(1:nstatv) = 0.0d0
        stress = 0.0d0
        dtl = 0.0d0
      end if
!     Cauchy stress at the start from ccx's PK2: sigma = F S F^T / J
      xj0 = cfmad_det3(dfgrd0)
      do k = 1, 6
        s(ia(k),ja(k)) = stress(k)
        s(ja(k),ia(k)) = stress(k)
      end do
      t = matmul(matmul(dfgrd0, s), transpose(dfgrd0)) / xj0
      do k = 1, 6
        sig(k) = t(ia(k),ja(k))
      end do
      pnew = 1.0d0
      e1 = 0.0d0
      e2 = 0.0d0
      e3 = 0.0d0
      e4 = 0.0d0
      e5 = 0.0d0
      e6 = 0.0d0
      e7 = 0.0d0
      dd = 0.0d0
      found = 0
!     CFM-DISPATCH
      if (found .eq. 0) then
        write (*,'(a,a)') ' CFM-UMAT-ERROR unknown material ',
     &    trim(cmname)
        stop 3
      end if
      if (pnew .lt. 1.0d0) then
!       ccx 2.20 passes pnewdt = -1 and cuts the increment back when a
!       material returns 0 < pnewdt < 1 (automatic increments; fixed
!       ones stop with a divergence error). The iterate is rejected,
!       so the stress and tangent are left as they came in.
        write (*,'(a,i0,a,i0,a,g0)') ' CFM-UMAT-CUTBACK element ', noel,
     &    ' point ', npt, ' time ', time(2) + dtime
        if (pnewdt .le. 0.0d0 .or. pnewdt .gt. 0.5d0) pnewdt = 0.5d0
        return
      end if
      if (first) statev(1:nstatv) = 0.0d0
!     PK2 at the end: S = J F^-1 sigma F^-T
      f = dfgrd1
      xj = cfmad_det3(f)
      call cfmad_inv3(f, fi)
      do k = 1, 6
        t(ia(k),ja(k)) = sig(k)
        t(ja(k),ia(k)) = sig(k)
      end do
      tau = xj * t
      s = xj * matmul(matmul(fi, t), transpose(fi))
      do k = 1, 6
        stress(k) = s(ia(k),ja(k))
      end do
!     spatial (Oldroyd-rate) tangent of tau from the Jaumann one:
!     c = J D - (delta_ik tau_jl + tau_ik delta_jl + delta_il tau_jk
!     + tau_il delta_jk) / 2, then pulled back: C_IJKL = F^-1 (4x) c
      do l = 1, 3
        do k = 1, 3
          do j = 1, 3
            do i = 1, 3
              c4(i,j,k,l) = xj * dd(iv(i,j),iv(k,l))
              if (i .eq. k) c4(i,j,k,l) = c4(i,j,k,l) - 0.5d0*tau(j,l)
              if (j .eq. l) c4(i,j,k,l) = c4(i,j,k,l) - 0.5d0*tau(i,k)
              if (i .eq. l) c4(i,j,k,l) = c4(i,j,k,l) - 0.5d0*tau(j,k)
              if (j .eq. k) c4(i,j,k,l) = c4(i,j,k,l) - 0.5d0*tau(i,l)
            end do
          end do
        end do
      end do
      do a = 1, 6
        do b = 1, 6
          ddsdde(a,b) = 0.0d0
          do l = 1, 3
            do k = 1, 3
              do j = 1, 3
                do i = 1, 3
                  p = ia(a)
                  q = ja(a)
                  r = ia(b)
                  m = ja(b)
                  ddsdde(a,b) = ddsdde(a,b) + fi(p,i)*fi(q,j)
     &              *fi(r,k)*fi(m,l)*c4(i,j,k,l)
                end do
              end do
            end do
          end do
        end do
      end do
      if (.false.) then
        spd = sse + scd + rpl + ddsddt(1) + drplde(1) + drpldt
     &    + stran(1) + dstran(1) + temp + dtemp + predef(1) + dpred(1)
     &    + coords(1) + drot(1,1) + celent + props(1)
     &    + dble(ndi + nshr + ntens + nstatv + nprops + layer + kspt
     &    + kstep(1) + kinc)
      end if
      end subroutine umat

!     CFM-HELPERS
