/* Diffusion theory for a slab: the dipole of Jensen et al. (2001) repeated about the
 * extrapolated boundaries of both faces, as in the multipole of Donner & Jensen (2005).
 *
 * The collimated beam is replaced by an isotropic point source of strength
 * (1 - R_specular) alpha' at depth z_r = 1/mu_t' (mu_s' = mu_s (1 - g), mu_t' = mu_a + mu_s',
 * alpha' = mu_s'/mu_t'). Each face gets the extrapolated boundary condition of its own index:
 * the fluence vanishes at distance z_b = 2 A D outside it, D = 1/(3 mu_t'),
 * A = (1 + F_dr)/(1 - F_dr) with F_dr the hemispherical Fresnel reflectance seen from inside.
 * Mirroring the source about both extrapolated planes gives positive sources at
 * z_r + 2kL and negative ones at -2 z_b,top - z_r + 2kL, L = d + z_b,top + z_b,bottom.
 * The transmitted exitance is Fick's flux -D dphi/dz at z = d. docs/transport.md has the
 * derivation and the closed-form total used by the tests. */
#include <math.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

typedef struct {
  double strength;   /* (1 - R_sp) alpha' / (4 pi) */
  double sigma_tr;   /* sqrt(3 mu_a mu_t') */
  double d, z_r, z_v, period;
  double a_below;    /* A of the exit face */
} Multipole;

/* Terms on each side of k = 0; the images recede by 2L per step, so their contributions to
 * the profile fall at least as 1/k^2 (as exp(-sigma_tr 2kL) with absorption). */
#define DS_MULTIPOLE_MAX_TERMS 200

static double
boundary_a (double n_inside, double n_outside)
{
  double fdr = ds_fresnel_diffuse_reflectance (n_inside, n_outside);
  return (1.0 + fdr) / (1.0 - fdr);
}

static void
multipole_init (const DsSlab *s, Multipole *m)
{
  double musp = s->mus * (1.0 - s->g);
  double mutp = s->mua + musp;
  double dcoef = 1.0 / (3.0 * mutp);
  double zb_top = 2.0 * boundary_a (s->n_medium, s->n_above) * dcoef;
  m->a_below = boundary_a (s->n_medium, s->n_below);
  double zb_bottom = 2.0 * m->a_below * dcoef;
  m->strength = (1.0 - ds_fresnel_reflectance (s->n_above, s->n_medium, 1.0)) * (musp / mutp) /
                (4.0 * G_PI);
  m->sigma_tr = sqrt (3.0 * s->mua * mutp);
  m->d = s->thickness_mm;
  m->z_r = 1.0 / mutp;
  m->z_v = -2.0 * zb_top - m->z_r;
  m->period = 2.0 * (s->thickness_mm + zb_top + zb_bottom);
}

/* Flux through z = d of one source of unit sign at depth z, lateral distance rho. */
static double
source_flux (const Multipole *m, double z, double rho)
{
  double h = m->d - z;
  double r = sqrt (rho * rho + h * h);
  if (r == 0.0)
    return 0.0; /* a source in the face itself sends nothing through it (odd in h) */
  return h * (1.0 + m->sigma_tr * r) * exp (-m->sigma_tr * r) / (r * r * r);
}

static double
multipole_profile (const Multipole *m, double rho)
{
  double sum = source_flux (m, m->z_r, rho) - source_flux (m, m->z_v, rho);
  for (int k = 1; k <= DS_MULTIPOLE_MAX_TERMS; k++) {
    double shift = k * m->period;
    double pair = source_flux (m, m->z_r + shift, rho) - source_flux (m, m->z_v + shift, rho) +
                  source_flux (m, m->z_r - shift, rho) - source_flux (m, m->z_v - shift, rho);
    sum += pair;
    if (fabs (pair) <= 1e-12 * fabs (sum))
      break;
  }
  return m->strength * sum;
}

/* Integral over the whole face of one family of sources z0 + kP (k in Z), unit sign, in units
 * of 2 pi: each source sends sign(h) exp(-sigma_tr |h|) (h = d - z) through the plane, and the
 * family is two geometric series. Summing in this order matters: without absorption the
 * terms are +-1 and the series only converges as the limit sigma_tr -> 0, (P - 2a)/P. */
static double
family_total (const Multipole *m, double z0)
{
  double p = m->period, h = m->d - z0;
  double a = h - p * floor (h / p); /* distance to the nearest source in front of the face */
  if (a <= 0.0)
    return 0.0; /* a source on the face itself: the series cancel pairwise */
  double s = m->sigma_tr;
  if (s * p < 1e-9)
    return (p - 2.0 * a) / p;
  return (exp (-s * a) - exp (-s * (p - a))) / -expm1 (-s * p);
}

double
ds_slab_diffusion_profile (const DsSlab *slab, double rho_mm)
{
  Multipole m;
  multipole_init (slab, &m);
  return multipole_profile (&m, rho_mm);
}

double
ds_slab_diffusion_transmittance (const DsSlab *slab)
{
  Multipole m;
  multipole_init (slab, &m);
  return m.strength * 2.0 * G_PI * (family_total (&m, m.z_r) - family_total (&m, m.z_v));
}

/* Diffuse radiance just inside the exit face, L(mu) ~ phi/(4 pi) + 3 F mu/(4 pi) with the
 * extrapolated-boundary ratio F = phi/(2A): weight 1 + 3 mu/(2A). What crosses the face is
 * (1 - R(mu)) L(mu) mu dmu; etendue conservation maps the outside cone to an inside one. */
static double
exit_flux (const DsSlab *s, double a, double mu_lo)
{
  const int n = 4000;
  double sum = 0.0, w = (1.0 - mu_lo) / n;
  for (int i = 0; i < n; i++) {
    double mu = mu_lo + (i + 0.5) * w;
    sum += (1.0 - ds_fresnel_reflectance (s->n_medium, s->n_below, mu)) * (1.0 + 1.5 * mu / a) * mu;
  }
  return sum * w;
}

double
ds_slab_diffusion_cone_fraction (const DsSlab *slab, double acceptance_half_angle_deg)
{
  if (acceptance_half_angle_deg >= 90.0)
    return 1.0;
  double a = boundary_a (slab->n_medium, slab->n_below);
  double sin_in = slab->n_below / slab->n_medium * sin (acceptance_half_angle_deg * G_PI / 180.0);
  if (sin_in >= 1.0)
    return 1.0;
  double mu_lo = sqrt (1.0 - sin_in * sin_in);
  return exit_flux (slab, a, mu_lo) / exit_flux (slab, a, 0.0);
}

DsImage *
ds_slab_psf_diffusion (const DsSlab *slab, const DsPsfGrid *grid, GError **error)
{
  if (!ds_slab_validate (slab, error) || !ds_psf_grid_validate (grid, error))
    return NULL;
  if (!(slab->mus * (1.0 - slab->g) > 0)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID,
                 "slab: diffusion needs a reduced scattering coefficient mus (1 - g) > 0 "
                 "(mus = %g, g = %g)", slab->mus, slab->g);
    return NULL;
  }
  guint r = grid->radius_px, side = 2 * r + 1;
  g_autoptr (DsImage) psf = ds_image_new (DS_SAMPLE_F32, side, side, error);
  if (!psf)
    return NULL;
  Multipole m;
  multipole_init (slab, &m);
  double cone = ds_slab_diffusion_cone_fraction (slab, grid->acceptance_half_angle_deg);
  double p = grid->pixel_pitch_mm;
  /* The profile's narrowest feature is the distance from the face to the nearest source. */
  double h_min = MAX (fabs (m.d - m.z_r), 1e-3 * m.d);
  /* Radial symmetry: compute the octant 0 <= j <= i, mirror the other seven. */
  for (guint i = 0; i <= r; i++)
    for (guint j = 0; j <= i; j++) {
      double rho_c = p * hypot (i, j);
      int n = (int) ceil (4.0 * p / MAX (rho_c, h_min));
      n = CLAMP (n, 4, 32);
      double sum = 0.0;
      for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++) {
          double x = p * (i - 0.5 + (a + 0.5) / n), y = p * (j - 0.5 + (b + 0.5) / n);
          sum += multipole_profile (&m, hypot (x, y));
        }
      /* Outside its validity (a slab thinner than 1/mu_t') the image sum can dip below zero;
       * negative light is clamped away. */
      float v = (float) MAX (0.0, cone * sum * p * p / ((double) n * n));
      int coords[8][2] = { { (int) i, (int) j }, { (int) j, (int) i }, { -(int) i, (int) j },
                           { -(int) j, (int) i }, { (int) i, -(int) j }, { (int) j, -(int) i },
                           { -(int) i, -(int) j }, { -(int) j, -(int) i } };
      for (int c = 0; c < 8; c++)
        ((float *) ds_image_row (psf, (guint) (coords[c][1] + (int) r)))[coords[c][0] + (int) r] = v;
    }
  return g_steal_pointer (&psf);
}
