/* Fresnel equations for unpolarized light at a plane interface between non-absorbing media. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Reflectance of light going from index n1 into n2 at incidence cosine cos_theta_i (its sign
 * is ignored): the mean of the s and p reflectances; 1 beyond the critical angle. */
double ds_fresnel_reflectance (double n1, double n2, double cos_theta_i);
/* The s- and p-polarized reflectances separately (both 1 beyond the critical angle). */
void ds_fresnel_reflectance_sp (double n1, double n2, double cos_theta_i, double *rs, double *rp);
/* Cosine of the refracted angle in n2 (Snell), or 0 with total internal reflection. */
double ds_fresnel_cos_transmitted (double n1, double n2, double cos_theta_i);
/* Hemispherical (diffuse) reflectance seen from n1: integral of 2 mu R(mu) dmu over 0..1,
 * computed numerically (it is the F_dr of diffusion boundary conditions). */
double ds_fresnel_diffuse_reflectance (double n1, double n2);

G_END_DECLS
