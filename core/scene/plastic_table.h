// roughplastic's rough-interface tables (layout: kernels/shared/plastic_table.h), computed on the
// host in double precision by the quadratures of Mitsuba 3's include/mitsuba/render/microfacet.h
// (eval_transmittance, eval_reflectance) and src/bsdfs/roughplastic.cpp (parameters_changed).
#pragma once

#include <vector>

namespace tandem {

/// Mitsuba's eval_transmittance for GGX: the share of light arriving from outside at cos_theta in
/// (0, 1] that a rough dielectric interface (roughness alpha, relative IOR eta = int/ext)
/// transmits in one scattering, the integral over the visible normals m of wi of
/// (1 - F(wi.m)) G1(wo, m), wo refracted about m and below the surface. Gauss-Legendre on
/// res x res nodes (res even) of the visible-normal sample square (Heitz 2018's map).
double rough_dielectric_transmittance(double alpha, double cos_theta, double eta, int res);

/// Mitsuba's eval_reflectance for GGX: the same with F(wi.m) G1(wo, m), wo reflected and above.
double rough_dielectric_reflectance(double alpha, double cos_theta, double eta, int res);

/// Mitsuba's m_internal_reflectance: 2 mean_k R(mu_k) mu_k over its 64 nodes
/// mu_k = max(1e-6, k / 63), R = rough_dielectric_reflectance(alpha, mu_k, 1 / eta, res).
double rough_internal_reflectance(double alpha, double eta, int res);

/// The quadrature resolutions the table uses (Mitsuba: 32 where the incident side is the less
/// dense one, else 128, where total internal reflection puts a kink in the integrand).
int plastic_transmittance_res(double eta);
int plastic_reflectance_res(double eta);

/// The table of relative IOR eta: PLASTIC_TABLE_FLOATS floats, node values in double rounded to
/// float, slopes by central differences of the same quadratures (transmittance) or of a cubic
/// spline through the nodes (internal reflectance). Computed on first use and kept for the
/// process; thread-safe.
const std::vector<float>& plastic_table(float eta);

} // namespace tandem
