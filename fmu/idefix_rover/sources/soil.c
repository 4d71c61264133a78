/* Soil: Bekker pressure-sinkage, Janosi-Hanamoto shear, and the persistent plastic-sinkage
 * (rut) grid. Equations in docs/rover-model.md, section "Soil". */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "idefix.h"

int soil_grid_init(SoilGrid *g, double x_min, double y_min, double x_max, double y_max,
                   double cell)
{
    long nx, ny;
    soil_grid_free(g);
    if (!(cell > 0.0)) cell = 0.01;
    /* coarsen rather than exhaust memory on a very large terrain */
    for (;;) {
        nx = (long)ceil((x_max - x_min) / cell) + 1;
        ny = (long)ceil((y_max - y_min) / cell) + 1;
        if (nx * ny <= MAX_GRID_CELLS) break;
        cell *= 1.5;
    }
    g->cell = cell;
    g->x0 = x_min;
    g->y0 = y_min;
    g->nx = nx;
    g->ny = ny;
    g->sinkage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->mark_travel = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->owner = (unsigned char *)calloc((size_t)(nx * ny), 1);
    g->prior_sinkage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->prior_disturbed = (unsigned char *)calloc((size_t)(nx * ny), 1);
    if (!g->sinkage || !g->mark_travel || !g->owner || !g->prior_sinkage || !g->prior_disturbed) {
        soil_grid_free(g);
        return -1;
    }
    g->dirty_i0 = nx;
    g->dirty_j0 = ny;
    g->dirty_i1 = -1;
    g->dirty_j1 = -1;
    return 0;
}

void soil_grid_free(SoilGrid *g)
{
    free(g->sinkage);
    free(g->mark_travel);
    free(g->owner);
    free(g->prior_sinkage);
    free(g->prior_disturbed);
    memset(g, 0, sizeof(*g));
}

/* Only the rectangle the wheels touched is cleared: a reset costs what the last run drove. */
void soil_grid_clear(SoilGrid *g)
{
    long j;
    if (!g->sinkage || g->dirty_i1 < g->dirty_i0) return;
    for (j = g->dirty_j0; j <= g->dirty_j1; j++) {
        long start = j * g->nx + g->dirty_i0, count = g->dirty_i1 - g->dirty_i0 + 1;
        memset(g->sinkage + start, 0, (size_t)count * sizeof(float));
        memset(g->mark_travel + start, 0, (size_t)count * sizeof(float));
        memset(g->owner + start, 0, (size_t)count);
        memset(g->prior_sinkage + start, 0, (size_t)count * sizeof(float));
        memset(g->prior_disturbed + start, 0, (size_t)count);
    }
    g->dirty_i0 = g->nx;
    g->dirty_j0 = g->ny;
    g->dirty_i1 = -1;
    g->dirty_j1 = -1;
}

#define MAX_PATCH_SAMPLES 64

/* Cells under the contact patch: a rectangle of the given length along the heading (hx, hy)
 * and width across it, centred at (cx, cy), sampled at half-cell spacing (-1: off the grid).
 * Returns the number of samples written to cells. */
static int patch_cells(const SoilGrid *g, double cx, double cy, double hx, double hy,
                       double length, double width, long *cells)
{
    int na = (int)ceil(length / (0.5 * g->cell)) + 1, nw = (int)ceil(width / (0.5 * g->cell)) + 1;
    int ia, iw, count = 0;
    if (na > MAX_PATCH_SAMPLES) na = MAX_PATCH_SAMPLES;
    if (nw > MAX_PATCH_SAMPLES) nw = MAX_PATCH_SAMPLES;
    if (nw < 2) nw = 2;
    for (ia = 0; ia < na; ia++) {
        double d = na > 1 ? -0.5 * length + length * ia / (na - 1) : 0.0;
        for (iw = 0; iw < nw; iw++) {
            double e = -0.5 * width + width * iw / (nw - 1);
            double sx = cx + d * hx - e * hy, sy = cy + d * hy + e * hx;
            long i = (long)floor((sx - g->x0) / g->cell), j = (long)floor((sy - g->y0) / g->cell);
            cells[count++] = (i < 0 || j < 0 || i >= g->nx || j >= g->ny) ? -1 : j * g->nx + i;
        }
    }
    return count;
}

/* A cell belongs to the wheel's current contact when this wheel pressed it last and has since
 * travelled less than the patch's extent along its motion (own_span): the cell is still under
 * the patch that pressed it. Once the wheel has rolled on by more, the cell is a rut it left,
 * and coming back over it (reversing, or a loop) is a second pass, however long ago. */
static int own_patch(const SoilGrid *g, long k, int wheel, double travel, double own_span)
{
    return g->owner[k] == wheel + 1 && travel - (double)g->mark_travel[k] <= own_span;
}

RutState soil_query(const SoilGrid *g, double cx, double cy, double hx, double hy, double length,
                    double width, int wheel, double travel, double own_span)
{
    RutState state = {0.0, 0.0};
    long cells[MAX_PATCH_SAMPLES * MAX_PATCH_SAMPLES];
    int n, s;
    if (!g->sinkage) return state;
    n = patch_cells(g, cx, cy, hx, hy, length, width, cells);
    for (s = 0; s < n; s++) {
        long k = cells[s];
        if (k < 0) continue;
        if (own_patch(g, k, wheel, travel, own_span)) {
            /* under this wheel's own moving patch: the soil as the wheel found it */
            state.rut_depth += g->prior_sinkage[k];
            state.disturbed += g->prior_disturbed[k];
        } else if (g->owner[k]) {
            state.rut_depth += g->sinkage[k];
            state.disturbed += 1.0;
        }
    }
    if (n > 0) {
        state.rut_depth /= (double)n;
        state.disturbed /= (double)n;
    }
    return state;
}

void soil_mark(SoilGrid *g, double cx, double cy, double hx, double hy, double length,
               double width, double sinkage, int wheel, double travel, double own_span)
{
    long cells[MAX_PATCH_SAMPLES * MAX_PATCH_SAMPLES];
    int n, s;
    if (!g->sinkage) return;
    n = patch_cells(g, cx, cy, hx, hy, length, width, cells);
    for (s = 0; s < n; s++) {
        long k = cells[s], i, j;
        if (k < 0) continue;
        i = k % g->nx;
        j = k / g->nx;
        if (!own_patch(g, k, wheel, travel, own_span)) {
            /* a new pass over this cell: remember the soil as this wheel finds it */
            g->prior_sinkage[k] = g->sinkage[k];
            g->prior_disturbed[k] = g->owner[k] != 0;
        }
        g->owner[k] = (unsigned char)(wheel + 1);
        g->mark_travel[k] = (float)travel;
        if ((float)sinkage > g->sinkage[k]) g->sinkage[k] = (float)sinkage;
        if (i < g->dirty_i0) g->dirty_i0 = i;
        if (i > g->dirty_i1) g->dirty_i1 = i;
        if (j < g->dirty_j0) g->dirty_j0 = j;
        if (j > g->dirty_j1) g->dirty_j1 = j;
    }
}

/* Pressure-sinkage modulus for milli-g: Reece's form p = (c k_c' + rho g b k_phi') (z/b)^n,
 * written with Bekker's moduli k_c, k_phi as measured on a reference soil (cohesion c_ref,
 * gravity g_ref): k_c' = k_c / c_ref, rho k_phi' = k_phi / g_ref. The cohesive part follows the
 * soil's cohesion, the frictional part the overburden rho g, so at Phobos' gravity it almost
 * vanishes. For n = 1 (the default) this is exact: p = ((c/c_ref) k_c / b + (g/g_ref) k_phi) z. */
double soil_modulus(const SoilParameters *s, double width)
{
    double kc = s->k_c * (s->reference_cohesion > 0.0 ? s->cohesion / s->reference_cohesion : 1.0);
    return kc / width + s->k_phi * s->gravity / s->reference_gravity;
}

/* Rigid wheel, p = k z^n integrated over the front arc:
 * W = b k sqrt(2r) z^(n+1/2) (3-n)/3  =>  z = [3W / ((3-n) b k sqrt(2r))]^(2/(2n+1)), bounded by
 * soil.max_sinkage. */
double bekker_static_sinkage(const SoilParameters *s, double load, double radius, double width)
{
    double k = soil_modulus(s, width), n = s->n, z;
    if (load <= 0.0 || width <= 0.0) return 0.0;
    if (k <= 0.0) return s->max_sinkage;
    z = pow(3.0 * load / ((3.0 - n) * width * k * sqrt(2.0 * radius)), 2.0 / (2.0 * n + 1.0));
    return z < s->max_sinkage ? z : s->max_sinkage;
}

/* Slip sinkage (Lyasko): z = z0 (1 + s) / (1 - 0.5 s) for driving slip s in [0, 1). */
double slip_sinkage(double static_sinkage, double slip)
{
    double s = slip < 0.0 ? 0.0 : (slip > 0.95 ? 0.95 : slip);
    return static_sinkage * (1.0 + s) / (1.0 - 0.5 * s);
}

/* Passive resistance of the soil beside a wheel sliding sideways (Bekker's bulldozing on the
 * wheel's side face, length x sinkage): R = L z c K_c, K_c = (N_c - tan phi) cos^2 phi with
 * Prandtl's N_c = (N_q - 1) cot phi, N_q = e^(pi tan phi) tan^2(45 deg + phi/2). The gravity
 * term (z^2 rho g K_gamma / 2) is left out: at Phobos' gravity it is below 1e-4 of the cohesive
 * one. The caller bounds R by the wheel load. */
double lateral_bulldozing(const SoilParameters *s, double cohesion, double length, double sinkage)
{
    const double pi = 3.141592653589793;
    double t = tan(s->friction_angle), nq, nc, kc;
    if (t < 1e-6) {
        nc = 2.0 + pi;  /* the limit phi -> 0 */
    } else {
        nq = exp(pi * t) * pow(tan(0.25 * pi + 0.5 * s->friction_angle), 2.0);
        nc = (nq - 1.0) / t;
    }
    kc = (nc - t) * pow(cos(s->friction_angle), 2.0);
    return length * sinkage * cohesion * kc;
}

/* Work of compacting the soil from the rut depth to the new sinkage, per unit travel. */
double compaction_resistance(const SoilParameters *s, double sinkage, double rut_depth,
                             double width)
{
    double k = soil_modulus(s, width), n = s->n;
    if (sinkage <= rut_depth) return 0.0;
    return width * k * (pow(sinkage, n + 1.0) - pow(rut_depth, n + 1.0)) / (n + 1.0);
}

/* Mean mobilised fraction of the shear strength over a patch whose rear end has been sheared
 * by j: (1/j) integral_0^j (1 - exp(-x/K)) dx = 1 - K/j (1 - exp(-j/K)). */
double janosi_mobilisation(double j, double K)
{
    double q;
    if (K <= 0.0) return 1.0;
    q = j / K;
    if (q < 1e-6) return 0.5 * q;
    return 1.0 - (1.0 - exp(-q)) / q;
}
