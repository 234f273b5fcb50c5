/* Light transport through a homogeneous slab (drivers/sim): Monte Carlo photon transport in the
 * style of MCML (Wang, Jacques & Zheng 1995) and the diffusion multipole (Jensen et al. 2001,
 * Donner & Jensen 2005), tallied as totals and as the lateral spread (PSF) of the light that
 * leaves the far face. docs/transport.md derives every approximation and lists the tests.
 *
 * Geometry: the slab fills 0 <= z <= thickness_mm; a unit pencil beam arrives at x = y = 0 along
 * +z from the medium of index n_above and leaves, transmitted, into the medium of index n_below.
 * Coefficients are per mm, lengths in mm. Every function is a pure function of its arguments
 * (and the seed): callable from any thread, no global state except the on-disk kernel cache. */
#pragma once
#include <glib.h>

#include "drivers/sim/fresnel.h"
#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  double mua, mus, g;   /* absorption, scattering (per mm), Henyey-Greenstein anisotropy */
  double thickness_mm;
  double n_medium;      /* refractive index of the slab */
  double n_above;       /* the medium the light enters from (z < 0) */
  double n_below;       /* the medium the transmitted light exits into (z > thickness) */
} DsSlab;

/* Checks g in (-1, 1), mua, mus >= 0 and finite, thickness > 0, every n >= 1. The error
 * (DS_SIM_ERROR_INVALID) names the parameter, its value and the allowed range. */
gboolean ds_slab_validate (const DsSlab *slab, GError **error);

/* Fractions of a unit normally incident pencil beam. They add up to one:
 * specular + reflectance + transmittance + absorbed = 1 (within Monte Carlo error).
 *   specular       Fresnel reflection at the entry face, exact: ((n_above-n)/(n_above+n))^2
 *   reflectance    light that entered and left again through the entry face (diffuse
 *                  reflectance, MCML's Rd; excludes the specular part)
 *   transmittance  everything that left through the far face, scattered or not (MCML's Tt)
 *   ballistic      the part of transmittance that never scattered (it includes unscattered
 *                  light internally reflected back and forth between the faces)
 *   absorbed       weight deposited in the slab
 *   scattered_in_cone  transmitted after >= 1 scattering and leaving within the acceptance
 *                  cone (ds_mc_slab_run: the whole hemisphere, i.e. transmittance - ballistic)
 * se_* are standard errors of the mean from the per-photon variance. */
typedef struct {
  double reflectance, transmittance, ballistic, absorbed;
  double se_reflectance, se_transmittance, se_ballistic, se_absorbed;
  guint64 photons;
  double specular;
  double scattered_in_cone, se_scattered_in_cone;
} DsSlabTally;

gboolean ds_mc_slab_run (const DsSlab *slab, guint64 photons, guint64 seed, DsSlabTally *out,
                         GError **error);
/* As ds_mc_slab_run, and scattered_in_cone counts only light leaving the far face within
 * acceptance_half_angle_deg (0 < angle <= 90, measured in the exit medium n_below). */
gboolean ds_mc_slab_run_cone (const DsSlab *slab, guint64 photons, guint64 seed,
                              double acceptance_half_angle_deg, DsSlabTally *out, GError **error);

/* As ds_mc_slab_run_cone with an explicit number of worker threads (0: one per processor;
 * the other functions use 0). The photons are split into 16 fixed chunks, each with its own
 * random stream (ds_rng_seed_stream), added in chunk order: the result is the same bits for
 * any number of threads. */
gboolean ds_mc_slab_run_threads (const DsSlab *slab, guint64 photons, guint64 seed,
                                 double acceptance_half_angle_deg, guint threads,
                                 DsSlabTally *out, GError **error);

typedef struct {
  double pixel_pitch_mm;             /* lateral size of one kernel pixel */
  guint radius_px;                   /* kernel is (2r+1) x (2r+1), centre at (r, r) */
  double acceptance_half_angle_deg;  /* in the exit medium; 90 = the whole hemisphere */
} DsPsfGrid;

/* Checks pixel_pitch_mm > 0, radius_px <= 2048, acceptance half-angle in (0, 90]; the error
 * (DS_SIM_ERROR_INVALID) names the field and its range. */
gboolean ds_psf_grid_validate (const DsPsfGrid *grid, GError **error);

/* f32 (2r+1)x(2r+1) kernel: the fraction of a unit collimated, normally incident pencil beam
 * (specular loss at entry included) that leaves the far face SCATTERED (at least one scattering
 * event) within the acceptance cone, per pixel of lateral offset (pixel (r, r) is offset 0).
 * The ballistic part is NOT included: the renderer adds exp(-sigma_t d) x Fresnel itself.
 * Light landing beyond the kernel is dropped, so the sum is the scattered transmitted fraction
 * within the cone and within the kernel. Errors: DS_SIM_ERROR_INVALID (slab, grid, photons). */
DsImage *ds_slab_psf_monte_carlo (const DsSlab *slab, const DsPsfGrid *grid, guint64 photons,
                                  guint64 seed, GError **error);

/* As ds_slab_psf_monte_carlo with an explicit number of worker threads (0: one per
 * processor); same bits for any number. With the same seed and photons the kernel's light is
 * exactly the scattered_in_cone light of ds_mc_slab_run_cone. */
DsImage *ds_slab_psf_monte_carlo_threads (const DsSlab *slab, const DsPsfGrid *grid,
                                          guint64 photons, guint64 seed, guint threads,
                                          GError **error);

/* The same kernel from diffusion theory: the multipole transmittance profile T(rho) (point
 * source at depth 1/mu_t', images about extrapolated boundaries at both faces, each face with
 * its own index) integrated over each pixel, times the fraction of the diffuse exitance that
 * leaves within the acceptance cone (diffusion radiance 1 + 3 mu/(2A) inside, Fresnel at the
 * face; docs/transport.md). Valid for optically thick slabs (mu_s' >> mu_a, d >> 1/mu_s');
 * outside that the image sum can dip below zero and such pixels are clamped to 0. */
DsImage *ds_slab_psf_diffusion (const DsSlab *slab, const DsPsfGrid *grid, GError **error);

/* Diffusion theory pieces, exposed for tests and tools: transmitted exitance per unit area at
 * lateral offset rho (per mm^2), its closed-form integral over the face, and the fraction of
 * the diffuse exitance within the cone. */
double ds_slab_diffusion_profile (const DsSlab *slab, double rho_mm);
double ds_slab_diffusion_transmittance (const DsSlab *slab);
double ds_slab_diffusion_cone_fraction (const DsSlab *slab, double acceptance_half_angle_deg);

typedef enum { DS_TRANSPORT_MONTE_CARLO, DS_TRANSPORT_DIFFUSION } DsTransportModel;

/* Object planes inside the slab (docs/transport.md, "Object planes"): thin layers at these
 * depths whose transmittance acts on the light each time it crosses them. */
#define DS_SLAB_MAX_PLANES 8
typedef struct {
  guint n_planes;
  double depth_mm[DS_SLAB_MAX_PLANES]; /* strictly increasing, inside (0, thickness) */
} DsSlabPlanes;

/* Checks the count and that depths increase strictly inside (0, thickness): DS_SIM_ERROR_INVALID
 * naming the plane. NULL planes are valid (none). */
gboolean ds_slab_planes_validate (const DsSlab *slab, const DsSlabPlanes *planes, GError **error);

/* One stretch of the slab between consecutive planes: segment 0 starts at the entry face,
 * segment j at the last crossing of plane j (1-based), the last ends at the exit face; each
 * ends where the light first crosses the next plane. Light at the start is split by whether it
 * is still unscattered (it came straight down the beam and crosses the plane once) or not: the
 * two arrive with different angular distributions, so each has its own kernel. Kernels are per
 * unit of light of that kind at the start (segment 0: per unit of the incident beam), f32
 * (2r+1)^2 centred on the start position; `stays_ballistic` is the share of the unscattered
 * light that is still unscattered at the end (0 for the last segment: kernels count scattered
 * light only). */
typedef struct {
  DsImage *from_ballistic;
  DsImage *from_scattered;   /* NULL in segment 0: all light enters unscattered */
  double stays_ballistic;
} DsSlabSegment;

/* What happens at plane j between the light's first and last crossing. Of the light arriving
 * unscattered / scattered at its first crossing (per unit of each), `once_*` crosses only once;
 * the rest crosses again (scattered back up, then down) and `recross_*` is where its last
 * crossing lies relative to the first, the kernel's sum being that rest's share. Of the light
 * crossing more than once, `recross_times` is the share crossing 3, 5, >= 7 times. */
#define DS_SLAB_RECROSS_CLASSES 3
typedef struct {
  double once_ballistic, once_scattered;
  DsImage *recross_ballistic, *recross_scattered;
  double recross_times[DS_SLAB_RECROSS_CLASSES];
} DsSlabPlaneCrossing;

/* Everything the renderer needs of the slab's scattering. `full` is the whole slab's kernel (as
 * ds_slab_psf_*: scattered light within the cone per pixel, fraction of a unit beam); with
 * planes, the segments and crossings chain it from plane to plane (docs/transport.md, "Object
 * planes"), all from the same photons. The radius holds `energy_fraction` of the scattered light
 * within the cone. */
typedef struct {
  DsTransportModel model;
  double pixel_pitch_mm;
  double acceptance_half_angle_deg;
  guint radius_px;
  DsImage *full;
  DsSlabPlanes planes;
  DsSlabSegment segments[DS_SLAB_MAX_PLANES + 1];
  DsSlabPlaneCrossing crossings[DS_SLAB_MAX_PLANES]; /* crossings[j - 1] for plane j */
  double scattered_in_cone, se_scattered_in_cone; /* all of it, also beyond the kernel */
  double held;            /* the share of scattered_in_cone inside `full` */
  double energy_fraction; /* the share the radius was chosen to hold */
  guint64 photons, records; /* Monte Carlo photons launched, records binned (0 for pure diffusion) */
  /* (sum w)^2 / sum w^2 of the records behind `full`: the Fourier coefficient of that many
   * random positions is ~ 1/sqrt(this), the floor below which an MTF is Monte Carlo noise
   * (0 for diffusion: no noise). */
  double effective_records;
} DsSlabKernels;

typedef struct {
  DsTransportModel model;
  double pixel_pitch_mm;
  double acceptance_half_angle_deg; /* in the exit medium */
  double energy_fraction;           /* (0, 1): e.g. 0.995 */
  guint64 photons, seed;            /* Monte Carlo (and, with planes, the segments of diffusion) */
  DsSlabPlanes planes;
} DsSlabKernelSpec;

/* Monte Carlo: one run records every photon that leaves the far face scattered in the cone
 * (exit position, weight, and per plane where it first crossed, whether it was unscattered
 * then, and how often it crossed); the radius is the smallest square holding energy_fraction
 * of that light (capped at 2048 px, `held` says what it holds), then all kernels are binned.
 * Diffusion: `full` from the multipole at the radius whose disc holds energy_fraction of its
 * analytic profile; the segments (a first-crossing distribution diffusion cannot give) from
 * Monte Carlo with the spec's photons and seed. threads 0: one per processor, same bits. */
DsSlabKernels *ds_slab_kernels_compute (const DsSlab *slab, const DsSlabKernelSpec *spec, guint threads,
                                        GError **error);
/* ds_slab_kernels_compute through an on-disk cache. The key is a SHA-256 of every parameter
 * that shapes the kernels (slab, spec with its planes, code version; photons and seed only
 * where Monte Carlo runs). Files live under cache_dir (NULL: $XDG_CACHE_HOME/descatter/psf,
 * else g_get_user_cache_dir()/descatter/psf), are written atomically (temporary file + rename)
 * and carry their key and a checksum: a file that is damaged or belongs to another key is
 * recomputed, never trusted. A cache that cannot be written is reported with g_message and the
 * computed kernels are returned anyway. *from_cache (may be NULL) says where they came from. */
DsSlabKernels *ds_slab_kernels_cached (const DsSlab *slab, const DsSlabKernelSpec *spec, const char *cache_dir,
                                       gboolean *from_cache, GError **error);
void ds_slab_kernels_free (DsSlabKernels *k);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSlabKernels, ds_slab_kernels_free)

/* |sum K(x, y) e^(-2 pi i x / period)| / sum K over a kernel (f32): its modulation transfer at
 * the stripe frequency, along x. The share of scattered light that still carries the stripes. */
double ds_kernel_mtf_x (const DsImage *kernel, double period_px);

/* `descatter-sim slab ...` (docs/transport.md): prints the Monte Carlo tally. Returns the exit
 * status: 0 ok, 1 bad arguments or failure (message on stderr). */
int ds_sim_slab_main (int argc, char **argv);

G_END_DECLS
