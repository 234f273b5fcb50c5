/* The upper end of the error a thin forward-peaked film adds where the probe's loss stage flags
 * it (scene_probe_loss.h; docs/accuracy.md, "Thin forward-peaked films").
 *
 * Light such a film scatters into the lens's acceptance cone (half-angle θc in air, object side)
 * moves less than a pixel and passes for direct light, so the transmissive image reads D + S_in for
 * D: a relative bias b = S_in / D. The light is scattered inside the film and refracts at its exit
 * face, so the cone inside a film of index n is θm = asin (sin θc / n). In single scattering with
 * the Henyey-Greenstein phase function of anisotropy g, the share of the scattered light within
 * θm of the incident direction is
 *   F(g, θc) = (1 + g) / (2g) - (1 - g^2) / (2g) (1 + g^2 - 2g cos θc)^-1/2
 * ((1 - cos θc) / 2 at g = 0, 1 as g -> 1), and F grows with g at every θc. Normalise the
 * scene's lit level to the open field after the film's two faces: T' = D + S_in (all that reaches
 * the lens), with S_in = F S. The light lost, 1 - T', is at least what was scattered out
 * of the cone, (1 - F) S (absorption only adds to it), so
 *   S <= (1 - T') / (1 - F),  S_in <= F (1 - T') / (1 - F),  D >= T' - S_in,
 *   b <= F (1 - T') / ((1 - F) T' - F (1 - T')),
 * which grows with F, hence with g and θm, and as T' falls. The bound takes g at DS_FILM_MAX_G,
 * T' at the loss's upper confidence (the transmittance DS_PROBE_LOSS_Z standard uncertainties low)
 * over the faces, and the faces' and the cone's index at the least, DS_FILM_MIN_INDEX: the least
 * reflection credits the least of the loss to the faces, and the least refraction leaves the
 * widest cone inside. The bias is then exact for a film that only scatters; absorption, and multiple
 * scattering (which widens the angular spread, taking light out of the cone), only lower it.
 * Where (1 - F) T' <= F (1 - T') the direct light may be nil: no upper end.
 *
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The most forward-peaked film the bound allows for: tissue and polymer films scatter with g of
 * 0.85-0.95; a larger g puts more of the scattered light into the cone than the bound counts. */
#define DS_FILM_MAX_G 0.95
/* The least refractive index of a film's faces: fluoropolymers and water (1.30-1.33) are the
 * lowest of solid and liquid films, so at least this much of the loss is the faces' reflection. */
#define DS_FILM_MIN_INDEX 1.3

/* F(g, θ): the share of singly scattered light within half-angle theta_rad of the incident
 * direction, Henyey-Greenstein anisotropy g in [0, 1). */
double ds_film_cone_fraction (double g, double theta_rad);

/* The half-angle (rad) inside a film of index n of the cone of half-angle cone_half_angle_deg in air. */
double ds_film_inner_cone (double cone_half_angle_deg, double n);

/* The upper end of the film's bias b = S_in / D for a transmittance into the lens (against the
 * open field, faces included) of at least transmittance_low, through a cone of half-angle
 * cone_half_angle_deg in air, at g = DS_FILM_MAX_G and index DS_FILM_MIN_INDEX. INFINITY where
 * the light lost allows no direct light. */
double ds_film_bias_upper (double transmittance_low, double cone_half_angle_deg);

G_END_DECLS
