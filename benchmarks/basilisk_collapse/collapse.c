/*
  The granular column collapse of docs/nonhydrostatic.md ("An independent code:
  Basilisk's layered solver"), written for Basilisk's layered solver
  (src/layered/hydro.h and, built with -DNH=1, src/layered/nh.h; Popinet 2020,
  J. Comput. Phys. 418, 109609).  benchmarks/basilisk_collapse.py builds and runs
  it and measures its output as it measures multilayer's.

  The case: a = 7, L0 = 5 cm, H0 = 35 cm on a horizontal bed, walls at both ends,
  Jop, Forterre & Pouliquen (2006) mu(I) with mu_s = 0.38186, mu_2 = 0.64347,
  I_0 = 0.26602, grains d = 0.5 mm of density 2500 kg/m^3 in a bulk of 1500 kg/m^3,
  either the released rectangle [0, L0] x [0, H0] or the mound of the same height and
  volume H0 cos^2(pi x/(4 L0)) on [0, 2 L0] (cell averages).

  What Basilisk provides: the layered transport (hydro.h), the non-hydrostatic
  pressure phi on the layer interfaces and the implicit free surface (nh.h), the time
  step.  What this file adds:
  - the vertical shear stress of mu(I), implicit in the velocities of each column
    with the viscosity lagged (computed from the velocities before the solve),
    nu = mu(I) p/(|du/dz| + 1e-6 s^-1) capped at 100 m^2/s, where p (per unit bulk
    density) on the interface below layer l is g times the depth above it plus, with
    nh.h, phi there, clipped at 0; I = d |du/dz| sqrt(rho_p/(rho p)); no slip on the
    bed, no stress at the surface.  The acceleration of the step is added before the
    implicit solve and taken off after it, as src/layered/diffusion.h does;
  - a first-order conservative remap of the layers (thicknesses and every advected
    tracer: u, and w with nh.h) back to equal fractions of the depth after every step.

  Usage: ./collapse [shape=rectangle|mound] [cells=N] [layers=8] [cfl=0.5]
                    [dtmax=DT] [tolerance=1e-5] [tend=1.5] [friction_phi=1]
  Domain: hydrostatic x in [0, 2.08] with N = 65 x 2^k cells (1040: 2 mm);
  non-hydrostatic x in [0, 1.024] with N = 2^k cells (512: 2 mm).  cfl sets CFL
  (and, hydrostatic, CFL_H); dtmax caps every step (default 1e-3 s non-hydrostatic,
  none hydrostatic: the first non-hydrostatic step starts from rest, where the
  advection CFL sets no bound); tolerance sets Basilisk's TOLERANCE (nh.h's multigrid
  stops at a residual of TOLERANCE (h/dt)^2, h the mean layer thickness);
  friction_phi=0 leaves phi out of the friction's p (a diagnostic).
  Prints on stdout, every 0.01 s from 0 to tend, a line "t <time>" then one line
  "x H umax" per cell (H the depth, umax the largest |u| of its layers); on stderr a
  summary (steps, mass, multigrid solves stopped at NITERMAX short of their
  tolerance).
*/
#include "grid/multigrid1D.h"
#include "layered/hydro.h"
#if NH
# include "layered/nh.h"
# define NONHYDROSTATIC 1
#else
# define NONHYDROSTATIC 0
#endif

/* the case */
const double L_col = 0.05, H_col = 0.35;
const double mu_s = 0.38186, mu_2 = 0.64347, I_0 = 0.26602;
const double grain = 0.5e-3, rho_p = 2500., rho_bulk = 1500.;
/* the regularisation of the viscosity */
const double gamma_min = 1e-6, nu_cap = 100.;

/* run parameters (command line) */
int mound = 0;
double cfl = 0.5, tend = 1.5, friction_phi = 1.;
long unmet = 0;  /* multigrid solves stopped at NITERMAX cycles, short of their tolerance */

int main (int argc, char * argv[])
{
  double cells_arg = 0., layers_arg = 8., tol = 1e-5;
  double dtmax_arg = NONHYDROSTATIC ? 1e-3 : HUGE;
  struct { const char * key; double * value; } options[] = {
    {"cells", &cells_arg}, {"layers", &layers_arg}, {"cfl", &cfl}, {"dtmax", &dtmax_arg},
    {"tolerance", &tol}, {"tend", &tend}, {"friction_phi", &friction_phi}
  };
  int noptions = sizeof (options)/sizeof (options[0]);
  for (int a = 1; a < argc; a++) {
    bool known = !strcmp (argv[a], "shape=mound") || !strcmp (argv[a], "shape=rectangle");
    if (known)
      mound = !strcmp (argv[a], "shape=mound");
    for (int o = 0; o < noptions && !known; o++) {
      size_t n = strlen (options[o].key);
      if (!strncmp (argv[a], options[o].key, n) && argv[a][n] == '=') {
        *options[o].value = atof (argv[a] + n + 1);
        known = true;
      }
    }
    if (!known) {
      fprintf (stderr, "collapse: unknown argument '%s'\n", argv[a]);
      return 2;
    }
  }
  int cells = cells_arg;
  nl = layers_arg;
#if NH
  L0 = 1.024;
  int base = 1;
  if (!cells) cells = 512;
#else
  dimensions (nx = 65);
  L0 = 2.08;
  int base = 65;
  if (!cells) cells = 1040;
#endif
  int k = cells/base;
  if (cells % base || k < 1 || (k & (k - 1)) || nl < 1) {
    fprintf (stderr, "collapse: cells must be %d x 2^k and layers >= 1\n", base);
    return 2;
  }
  N = cells;
  X0 = 0.;
  G = 9.81;
  DT = dtmax_arg;
  TOLERANCE = tol;
  run();
}

/* depth of the initial column at [x - dx/2, x + dx/2] (cell average) */
static double initial_depth (double x, double dx)
{
  double a = x - dx/2., b = x + dx/2.;
  if (!mound)
    return b <= L_col ? H_col : a >= L_col ? 0. : H_col*(L_col - a)/dx;
  /* H0 cos^2(pi x/(4 L0)) = H0 (1 + cos(pi x/(2 L0)))/2 on [0, 2 L0] */
  double e = 2.*L_col;
  if (a >= e)
    return 0.;
  b = fmin (b, e);
  double k = M_PI/(2.*L_col);
  return H_col/2.*((b - a) + (sin (k*b) - sin (k*a))/k)/dx;
}

event init (i = 0)
{
  CFL = cfl;
#if !NH
  CFL_H = cfl;
#endif
  foreach() {
    zb[] = 0.;
    double H = initial_depth (x, Delta);
    foreach_layer()
      h[] = H/nl;
  }
}

/* mu(I) p/|gamma| regularised and capped, per unit bulk density (m^2/s) */
static double friction_viscosity (double gamma, double p)
{
  if (p <= 0.)
    return 0.;
  double g = fabs (gamma);
  double scale = grain*sqrt (rho_p/rho_bulk);  /* I = scale |gamma|/sqrt(p) */
  double mu = mu_s + (mu_2 - mu_s)*scale*g/(I_0*sqrt (p) + scale*g);
  double nu = mu*p/(g + gamma_min);
  return nu < nu_cap ? nu : nu_cap;
}

/* one implicit step of the vertical friction in the column at point */
static void column_friction (Point point)
{
  /* interface l lies below layer l; interface 0 is the bed (u = 0 below it) */
  double cond[nl + 1], diag[nl], rhs[nl];
  double above = 0.;
  for (int l = nl - 1; l >= 0; l--) {
    above += h[0,0,l];
    double p = G*above;
#if NH
    if (friction_phi != 0.)
      p += phi[0,0,l];
#endif
    double dz = l > 0 ? (h[0,0,l - 1] + h[0,0,l])/2. : h[0,0,0]/2.;
    double below = l > 0 ? u.x[0,0,l - 1] : 0.;
    double gamma = (u.x[0,0,l] - below)/dz;
    cond[l] = dt*friction_viscosity (gamma, p)/dz;
  }
  cond[nl] = 0.;
  /* tridiagonal: -cond[l] u[l-1] + (h[l] + cond[l] + cond[l+1]) u[l] - cond[l+1] u[l+1]
     = h[l] u*[l], eliminated downwards from the bed (the Thomas algorithm) */
  for (int l = 0; l < nl; l++) {
    diag[l] = h[0,0,l] + cond[l] + cond[l + 1];
    rhs[l] = h[0,0,l]*u.x[0,0,l];
    if (l > 0) {
      double f = cond[l]/diag[l - 1];
      diag[l] -= f*cond[l];
      rhs[l] += f*rhs[l - 1];
    }
  }
  double next = 0.;
  for (int l = nl - 1; l >= 0; l--) {
    next = (rhs[l] + cond[l + 1]*next)/diag[l];
    u.x[0,0,l] = next;
  }
}

/* depth of the column at point */
static double column_depth (Point point)
{
  double H = 0.;
  foreach_layer()
    H += h[];
  return H;
}

event viscous_term (i++)
{
  foreach() {
    if (column_depth (point) > dry) {
      foreach_layer()
        u.x[] += dt*(ha.x[] + ha.x[1])/(hf.x[] + hf.x[1] + dry);
      column_friction (point);
      foreach_layer()
        u.x[] -= dt*(ha.x[] + ha.x[1])/(hf.x[] + hf.x[1] + dry);
    }
  }
}

/* first-order conservative remap of a column to layers of equal thickness */
event remap (i++)
{
  foreach() {
    double H = column_depth (point);
    if (H > dry) {
      double top[nl], old[nl];
      double z = 0.;
      for (int l = 0; l < nl; l++)
        top[l] = (z += h[0,0,l]);
      double hn = H/nl;
      for (scalar s in tracers) {
        for (int l = 0; l < nl; l++)
          old[l] = s[0,0,l];
        int j = 0;  /* the old layer holding the bottom of the new one */
        for (int l = 0; l < nl; l++) {
          double lo = l*hn, hi = l == nl - 1 ? H : (l + 1)*hn, sum = 0.;
          while (j < nl - 1 && top[j] <= lo)
            j++;
          for (int m = j; m < nl; m++) {
            double b = m > 0 ? fmax (top[m - 1], lo) : lo;
            double e = fmin (top[m], hi);
            if (e > b)
              sum += (e - b)*old[m];
            if (top[m] >= hi)
              break;
          }
          s[0,0,l] = sum/(hi - lo);
        }
      }
      foreach_layer()
        h[] = hn;
    }
  }
}

#if NH
event count_unmet (i++)
{
  if (mgp.i >= NITERMAX)
    unmet++;
}
#endif

event output (t = 0; t <= tend + 1e-9; t += 0.01)
{
  printf ("t %.9g\n", t);
  foreach (serial) {
    double H = 0., umax = 0.;
    foreach_layer() {
      H += h[];
      if (fabs (u.x[]) > umax)
        umax = fabs (u.x[]);
    }
    printf ("%.9g %.12g %.9g\n", x, H, umax);
  }
  fflush (stdout);
}

event end (t = tend)
{
  double mass = 0.;
  foreach (serial) {
    foreach_layer()
      mass += h[]*Delta;
  }
  fprintf (stderr, "collapse: %s, %s, N = %d, nl = %d, CFL %g, DT %g, TOLERANCE %g: "
           "%d steps to t = %g, mass %.12g m^2, %ld multigrid solves not converged\n",
           mound ? "mound" : "rectangle", NONHYDROSTATIC ? "nh.h" : "hydro.h", N, nl, CFL, DT,
           TOLERANCE, i, t, mass, unmet);
}
