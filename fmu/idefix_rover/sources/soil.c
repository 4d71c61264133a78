/* Soil: Bekker pressure-sinkage, Janosi-Hanamoto shear, and the persistent plastic-sinkage
 * (rut) grid. Equations in docs/rover-model.md, section "Soil". */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "idefix.h"

/* The rut grid over [x_min, x_max] x [y_min, y_max]: 0, or -1 out of memory, -2 an extent
 * beyond a double. */
int soil_grid_init(SoilGrid *g, double x_min, double y_min, double x_max, double y_max,
                   double cell)
{
    long nx, ny;
    double side_x, side_y;
    soil_grid_free(g);
    if (!(cell > 0.0)) cell = 0.01;
    if (!isfinite(x_max - x_min) || !isfinite(y_max - y_min)) return -2;
    /* coarsen rather than exhaust memory on a very large terrain; the nodes are counted in
     * double (exact while they fit MAX_GRID_CELLS), so no count overflows a long on the way */
    for (;;) {
        side_x = ceil((x_max - x_min) / cell) + 1.0;
        side_y = ceil((y_max - y_min) / cell) + 1.0;
        if (side_x * side_y <= (double)MAX_GRID_CELLS) break;
        cell *= 1.5;
    }
    nx = (long)side_x;
    ny = (long)side_y;
    g->cell = cell;
    g->x0 = x_min;
    g->y0 = y_min;
    g->nx = nx;
    g->ny = ny;
    g->sinkage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->mark_travel = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->owner = (unsigned char *)calloc((size_t)(nx * ny), 1);
    g->coverage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->prior_sinkage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    g->prior_coverage = (float *)calloc((size_t)(nx * ny), sizeof(float));
    if (!g->sinkage || !g->coverage || !g->mark_travel || !g->owner || !g->prior_sinkage ||
        !g->prior_coverage) {
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
    free(g->coverage);
    free(g->prior_sinkage);
    free(g->prior_coverage);
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
        memset(g->coverage + start, 0, (size_t)count * sizeof(float));
        memset(g->prior_sinkage + start, 0, (size_t)count * sizeof(float));
        memset(g->prior_coverage + start, 0, (size_t)count * sizeof(float));
    }
    g->dirty_i0 = g->nx;
    g->dirty_j0 = g->ny;
    g->dirty_i1 = -1;
    g->dirty_j1 = -1;
}

#define MAX_PATCH_SAMPLES 64

/* Cell index of the grid coordinate u (in cells), clamped to -1 ... n before the cast: a point
 * far off the grid is off it, and no cast overflows. */
static long cell_index(double u, long n)
{
    double f = floor(u);
    return f < 0.0 ? -1 : (f >= (double)n ? n : (long)f);
}

/* Sample points of the contact patch: a rectangle of the given length along the heading
 * (hx, hy) and width across it, centred at (cx, cy), cut into equal parts no larger than half
 * a cell each way; a point at the centre of each part (the midpoint rule: no point on the
 * patch's edge, where a rut's edge may lie). Returns the number of points written to px, py. */
static int patch_points(const SoilGrid *g, double cx, double cy, double hx, double hy,
                        double length, double width, double *px, double *py)
{
    double parts_a = ceil(length / (0.5 * g->cell)), parts_w = ceil(width / (0.5 * g->cell));
    int na, nw, ia, iw, count = 0;
    /* clamped before the cast: a huge patch is sampled more coarsely, never overflows */
    na = parts_a < 1.0 ? 1 : (parts_a > MAX_PATCH_SAMPLES ? MAX_PATCH_SAMPLES : (int)parts_a);
    nw = parts_w < 1.0 ? 1 : (parts_w > MAX_PATCH_SAMPLES ? MAX_PATCH_SAMPLES : (int)parts_w);
    for (ia = 0; ia < na; ia++) {
        double d = length * ((ia + 0.5) / na - 0.5);
        for (iw = 0; iw < nw; iw++) {
            double e = width * ((iw + 0.5) / nw - 0.5);
            px[count] = cx + d * hx - e * hy;
            py[count] = cy + d * hy + e * hx;
            count++;
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

/* What cell k holds for this wheel: its mean rut depth and the fraction of it pressed. */
static void cell_state(const SoilGrid *g, long k, int wheel, double travel, double own_span,
                       double *depth, double *disturbed)
{
    if (own_patch(g, k, wheel, travel, own_span)) {
        /* under this wheel's own moving patch: the soil as the wheel found it */
        *depth = g->prior_sinkage[k];
        *disturbed = g->prior_coverage[k];
    } else if (g->owner[k]) {
        *depth = g->sinkage[k];
        *disturbed = g->coverage[k];
    } else {
        *depth = 0.0;
        *disturbed = 0.0;
    }
}

/* The state a reading wheel finds in cell (i, j); off the grid, fresh soil. */
static void cell_at(const SoilGrid *g, long i, long j, int wheel, double travel, double own_span,
                    double *depth, double *covered)
{
    if (i < 0 || j < 0 || i >= g->nx || j >= g->ny) {
        *depth = 0.0;
        *covered = 0.0;
        return;
    }
    cell_state(g, j * g->nx + i, wheel, travel, own_span, depth, covered);
}

/* The edge of the pressed area across a partly pressed cell (i, j), covered the fraction f:
 * a straight line normal to the gradient of the neighbours' covered fractions (Youngs'
 * stencil), placed so that it cuts off the fraction f (the piecewise-linear interface
 * reconstruction of volume-of-fluid methods: Youngs 1982; the line constant of Scardovelli &
 * Zaleski 2000, J. Comput. Phys. 164). In the cell's frame [0, 1]^2, mirrored so that both
 * components of the outward normal (m1, m2) are >= 0 (flip_u, flip_v) and ordered (swap), the
 * covered part is m1 x + m2 y <= alpha. Without a gradient (a partly pressed cell among equal
 * neighbours) the line is unknown (known = 0). */
typedef struct {
    double m1, m2, alpha;
    int flip_u, flip_v, swap, known;
} EdgeLine;

#define EDGE_CACHE 16

static void edge_line(const SoilGrid *g, long i, long j, double f, int wheel, double travel,
                      double own_span, EdgeLine *line)
{
    double n[3][3], depth, mx, my, m1, m2, v1, sum;
    int a, b;
    for (b = 0; b < 3; b++)
        for (a = 0; a < 3; a++)
            cell_at(g, i + a - 1, j + b - 1, wheel, travel, own_span, &depth, &n[b][a]);
    /* Youngs: the gradient of the fractions, corners weighted 1, edges 2; the covered side
     * lies along it, so the outward normal is its opposite */
    mx = (n[0][0] + 2.0 * n[1][0] + n[2][0]) - (n[0][2] + 2.0 * n[1][2] + n[2][2]);
    my = (n[0][0] + 2.0 * n[0][1] + n[0][2]) - (n[2][0] + 2.0 * n[2][1] + n[2][2]);
    sum = fabs(mx) + fabs(my);
    line->known = sum >= 1e-9;
    if (!line->known) return;
    line->flip_u = mx < 0.0;
    line->flip_v = my < 0.0;
    m1 = fabs(mx) / sum;
    m2 = fabs(my) / sum;
    line->swap = m1 > m2;
    if (line->swap) {  /* order the components: m1 <= m2 */
        double t = m1;
        m1 = m2;
        m2 = t;
    }
    v1 = 0.5 * m1 / m2;
    if (m1 <= 1e-12)
        line->alpha = f * m2;
    else if (f <= v1)
        line->alpha = sqrt(2.0 * m1 * m2 * f);
    else if (f <= 1.0 - v1)
        line->alpha = f * m2 + 0.5 * m1;
    else
        line->alpha = 1.0 - sqrt(2.0 * m1 * m2 * (1.0 - f));
    line->m1 = m1;
    line->m2 = m2;
}

/* Is the point (u, v) of the cell's [0, 1]^2 on the covered side of its edge line? 1 yes,
 * 0 no, -1 the line is unknown. */
static int edge_side(const EdgeLine *line, double u, double v)
{
    double x, y;
    if (!line->known) return -1;
    x = line->flip_u ? 1.0 - u : u;
    y = line->flip_v ? 1.0 - v : v;
    if (line->swap) {
        double t = x;
        x = y;
        y = t;
    }
    return line->m1 * x + line->m2 * y <= line->alpha;
}

/* The rut under the patch: the mean over its sample points of the cell each point is in. A
 * cell holds the mean depth over its area and the fraction of it the wheels pressed; in a
 * partly pressed cell a point reads the depth of the pressed part on that part and fresh soil
 * beside it (edge_line, edge_side), so that a rear wheel in its front wheel's rut finds the rut as
 * deep and as wide as it was pressed, wherever the rut's edge lies in a cell
 * (docs/rover-model.md, "The rut grid's resolution"). Off the grid is fresh soil. */
RutState soil_query(const SoilGrid *g, double cx, double cy, double hx, double hy, double length,
                    double width, int wheel, double travel, double own_span)
{
    RutState state = {0.0, 0.0};
    double px[MAX_PATCH_SAMPLES * MAX_PATCH_SAMPLES], py[MAX_PATCH_SAMPLES * MAX_PATCH_SAMPLES];
    /* the edge lines of the partly pressed cells, reconstructed once per query: several
     * sample points fall in each cell */
    long seen[EDGE_CACHE];
    EdgeLine lines[EDGE_CACHE];
    int n, s, cached = 0, replaced = 0;
    /* a pose or patch that is not a number reads fresh soil (and casts nothing undefined) */
    if (!g->sinkage || !isfinite(cx) || !isfinite(cy) || !isfinite(hx) || !isfinite(hy) ||
        !isfinite(length) || !isfinite(width))
        return state;
    n = patch_points(g, cx, cy, hx, hy, length, width, px, py);
    for (s = 0; s < n; s++) {
        double u = (px[s] - g->x0) / g->cell, v = (py[s] - g->y0) / g->cell;
        long i = cell_index(u, g->nx), j = cell_index(v, g->ny);
        double fi = (double)i, fj = (double)j, depth, covered;
        cell_at(g, i, j, wheel, travel, own_span, &depth, &covered);
        if (covered > 1e-6 && covered < 1.0 - 1e-6) {
            long key = j * g->nx + i;
            int c, side;
            for (c = 0; c < cached && seen[c] != key; c++) {}
            if (c == cached) {  /* not seen yet: a free slot, or the oldest one */
                if (cached < EDGE_CACHE)
                    cached++;
                else
                    c = replaced++ % EDGE_CACHE;
                edge_line(g, i, j, covered, wheel, travel, own_span, &lines[c]);
                seen[c] = key;
            }
            side = edge_side(&lines[c], u - fi, v - fj);
            if (side == 1) {
                depth /= covered;
                covered = 1.0;
            } else if (side == 0) {
                depth = 0.0;
                covered = 0.0;
            }
        }
        state.rut_depth += depth;
        state.disturbed += covered;
    }
    if (n > 0) {
        state.rut_depth /= (double)n;
        state.disturbed /= (double)n;
    }
    return state;
}

/* Fraction of the unit square where n1 u + n2 v <= t (the area cut off by a straight line; the
 * formula of Scardovelli & Zaleski 2000, J. Comput. Phys. 164, for the volume below a line). */
static double square_below(double n1, double n2, double t)
{
    double m1, m2, sum, alpha;
    if (n1 < 0.0) {  /* u -> 1 - u */
        t -= n1;
        n1 = -n1;
    }
    if (n2 < 0.0) {
        t -= n2;
        n2 = -n2;
    }
    sum = n1 + n2;
    if (sum <= 0.0) return t >= 0.0 ? 1.0 : 0.0;
    m1 = (n1 < n2 ? n1 : n2) / sum;
    m2 = (n1 < n2 ? n2 : n1) / sum;
    alpha = t / sum;
    if (alpha <= 0.0) return 0.0;
    if (alpha >= 1.0) return 1.0;
    if (alpha < m1) return alpha * alpha / (2.0 * m1 * m2);
    if (alpha <= m2) return (alpha - 0.5 * m1) / m2;
    return 1.0 - (1.0 - alpha) * (1.0 - alpha) / (2.0 * m1 * m2);
}

/* The patch's four sides as half-planes n_k . (p - centre) <= limit_k, n = +-heading (along),
 * +-normal (across), with the reach of a cell's corners beyond its corner (x0, y0) along each
 * normal, from low_k to high_k: worked out once per patch, not per cell. */
typedef struct {
    double nx[4], ny[4], limit[4], low[4], high[4];
} PatchSides;

static void patch_sides(PatchSides *p, double c, double hx, double hy, double length,
                        double width)
{
    int side;
    p->nx[0] = hx;
    p->nx[1] = -hx;
    p->nx[2] = -hy;
    p->nx[3] = hy;
    p->ny[0] = hy;
    p->ny[1] = -hy;
    p->ny[2] = hx;
    p->ny[3] = -hx;
    p->limit[0] = p->limit[1] = 0.5 * length;
    p->limit[2] = p->limit[3] = 0.5 * width;
    for (side = 0; side < 4; side++) {
        double nx = p->nx[side], ny = p->ny[side];
        p->low[side] = c * ((nx < 0.0 ? nx : 0.0) + (ny < 0.0 ? ny : 0.0));
        p->high[side] = c * ((nx > 0.0 ? nx : 0.0) + (ny > 0.0 ? ny : 0.0));
    }
}

/* Area fraction of the square cell [x0, x0 + c] x [y0, y0 + c] inside the rectangle of the
 * given length along the heading (hx, hy) and width across it, centred at (cx, cy), by
 * clipping the cell with the four sides (Sutherland-Hodgman) and the shoelace formula. */
static double clipped_overlap(double x0, double y0, double c, double cx, double cy, double hx,
                              double hy, double length, double width)
{
    const double corners[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    double pd[12], pe[12], qd[12], qe[12], area = 0.0;
    int side, k, n = 4;
    for (k = 0; k < 4; k++) {
        double x = x0 + corners[k][0] * c - cx, y = y0 + corners[k][1] * c - cy;
        pd[k] = x * hx + y * hy;       /* along the heading */
        pe[k] = -x * hy + y * hx;      /* across it */
    }
    for (side = 0; side < 4 && n > 0; side++) {
        /* keep sign * coordinate <= limit */
        int along = side < 2, m = 0;
        double sign = (side % 2) ? -1.0 : 1.0, limit = 0.5 * (along ? length : width);
        for (k = 0; k < n; k++) {
            int l = (k + 1) % n;
            double a = sign * (along ? pd[k] : pe[k]) - limit;
            double b = sign * (along ? pd[l] : pe[l]) - limit;
            if (a <= 0.0) {
                qd[m] = pd[k];
                qe[m] = pe[k];
                m++;
            }
            if ((a < 0.0 && b > 0.0) || (a > 0.0 && b < 0.0)) {
                double t = a / (a - b);
                qd[m] = pd[k] + t * (pd[l] - pd[k]);
                qe[m] = pe[k] + t * (pe[l] - pe[k]);
                m++;
            }
        }
        n = m;
        for (k = 0; k < n; k++) {
            pd[k] = qd[k];
            pe[k] = qe[k];
        }
    }
    for (k = 0; k < n; k++) {
        int l = (k + 1) % n;
        area += pd[k] * pe[l] - pd[l] * pe[k];
    }
    return 0.5 * fabs(area) / (c * c);
}

/* Fraction of the cell [x0, x0 + c] x [y0, y0 + c] inside the patch, given its corner's
 * distances along the sides' normals, base_k = n_k . ((x0, y0) - centre) (the caller's
 * products nx_k (x0 - cx) and ny_k (y0 - cy), summed here). A cell crossed by one side of the
 * patch is measured exactly by square_below; one crossed by two (at the patch's corners) is
 * clipped. So the covered fraction changes continuously as the patch moves. */
static double cell_overlap_at(const PatchSides *p, const double *x_term, const double *y_term,
                              double x0, double y0, double c, double cx, double cy, double hx,
                              double hy, double length, double width)
{
    double base[4];
    int side, crossing = 0, crossed = -1;
    for (side = 0; side < 4; side++) {
        base[side] = x_term[side] + y_term[side];
        if (base[side] + p->low[side] > p->limit[side]) return 0.0;  /* all corners beyond */
        if (base[side] + p->high[side] > p->limit[side]) {
            crossing++;
            crossed = side;
        }
    }
    if (crossing == 0) return 1.0;
    if (crossing == 1)
        return square_below(p->nx[crossed], p->ny[crossed],
                            (p->limit[crossed] - base[crossed]) / c);
    return clipped_overlap(x0, y0, c, cx, cy, hx, hy, length, width);
}

/* The wheel presses the cells under its patch. Each cell keeps the mean over its area: a pass
 * that covers the fraction f of it at sinkage z deepens it from the depth it had before the pass
 * by f (z - that depth), and disturbs that fraction of what was undisturbed; within one pass the
 * largest fraction counts, as the patch sweeps over the cell. */
void soil_mark(SoilGrid *g, double cx, double cy, double hx, double hy, double length,
               double width, double sinkage, int wheel, double travel, double own_span)
{
    double ax = 0.5 * (fabs(length * hx) + fabs(width * hy));
    double ay = 0.5 * (fabs(length * hy) + fabs(width * hx));
    long i0, i1, j0, j1, i, j;
    PatchSides sides;
    if (!g->sinkage || !(length > 0.0) || !(width > 0.0) || !isfinite(length) ||
        !isfinite(width) || !isfinite(cx) || !isfinite(cy) || !isfinite(hx) || !isfinite(hy))
        return;  /* nothing to mark (and no undefined cast of a NaN to a cell index) */
    i0 = cell_index((cx - ax - g->x0) / g->cell, g->nx);
    i1 = cell_index((cx + ax - g->x0) / g->cell, g->nx);
    j0 = cell_index((cy - ay - g->y0) / g->cell, g->ny);
    j1 = cell_index((cy + ay - g->y0) / g->cell, g->ny);
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 >= g->nx) i1 = g->nx - 1;
    if (j1 >= g->ny) j1 = g->ny - 1;
    patch_sides(&sides, g->cell, hx, hy, length, width);
    for (j = j0; j <= j1; j++) {
        double y0 = g->y0 + j * g->cell, y_term[4];
        int side;
        for (side = 0; side < 4; side++) y_term[side] = sides.ny[side] * (y0 - cy);
        for (i = i0; i <= i1; i++) {
            long k = j * g->nx + i;
            double x0 = g->x0 + i * g->cell, x_term[4], f, depth, covered;
            for (side = 0; side < 4; side++) x_term[side] = sides.nx[side] * (x0 - cx);
            f = cell_overlap_at(&sides, x_term, y_term, x0, y0, g->cell, cx, cy, hx, hy, length,
                                width);
            if (f <= 0.0) continue;
            if (f > 1.0) f = 1.0;
            if (!own_patch(g, k, wheel, travel, own_span)) {
                /* a new pass over this cell: remember the soil as this wheel finds it */
                g->prior_sinkage[k] = g->sinkage[k];
                g->prior_coverage[k] = g->coverage[k];
            }
            g->owner[k] = (unsigned char)(wheel + 1);
            g->mark_travel[k] = (float)travel;
            depth = g->prior_sinkage[k] + f * (sinkage > g->prior_sinkage[k] ?
                                               sinkage - g->prior_sinkage[k] : 0.0);
            covered = g->prior_coverage[k] + f * (1.0 - g->prior_coverage[k]);
            if ((float)depth > g->sinkage[k]) g->sinkage[k] = (float)depth;
            if ((float)covered > g->coverage[k]) g->coverage[k] = (float)covered;
            if (i < g->dirty_i0) g->dirty_i0 = i;
            if (i > g->dirty_i1) g->dirty_i1 = i;
            if (j < g->dirty_j0) g->dirty_j0 = j;
            if (j > g->dirty_j1) g->dirty_j1 = j;
        }
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
