/* Checks of the rut grid's geometry in soil.c against brute force (tests/fmu/test_fmu_soil.py):
 * the exact overlap of a patch with a cell, and the edge line reconstructed in a partly pressed
 * cell. Prints three figures; the test compares them with its tolerances. */
#include "soil.c"

#include <stdio.h>

static unsigned state = 12345u;

/* Fraction of one cell [x0, x0 + c] x [y0, y0 + c] inside the patch, as soil_mark works it out
 * (the sides once per patch, then the cell) */
static double cell_overlap(double x0, double y0, double c, double cx, double cy, double hx,
                           double hy, double length, double width)
{
    PatchSides p;
    double x_term[4], y_term[4];
    int side;
    patch_sides(&p, c, hx, hy, length, width);
    for (side = 0; side < 4; side++) {
        x_term[side] = p.nx[side] * (x0 - cx);
        y_term[side] = p.ny[side] * (y0 - cy);
    }
    return cell_overlap_at(&p, x_term, y_term, x0, y0, c, cx, cy, hx, hy, length, width);
}

static double uniform(void)
{
    state = state * 1103515245u + 12345u;
    return (state >> 8) / 16777216.0;
}

/* share of an N x N grid of points of the cell inside the patch */
static double brute_overlap(double x0, double y0, double c, double cx, double cy, double hx,
                            double hy, double length, double width)
{
    const int n = 400;
    int a, b, inside = 0;
    for (a = 0; a < n; a++)
        for (b = 0; b < n; b++) {
            double x = x0 + (a + 0.5) * c / n - cx, y = y0 + (b + 0.5) * c / n - cy;
            double d = x * hx + y * hy, e = -x * hy + y * hx;
            inside += fabs(d) <= 0.5 * length && fabs(e) <= 0.5 * width;
        }
    return (double)inside / ((double)n * n);
}

int main(void)
{
    double worst_overlap = 0.0, worst_sum = 0.0;
    long wrong = 0, total = 0;
    int t, k;
    SoilGrid g;
    memset(&g, 0, sizeof(g));
    /* 1. a patch over a cell at any heading: the exact fraction, and the fractions of all the
     * cells it touches sum to its area */
    for (t = 0; t < 2000; t++) {
        double yaw = 6.283185307179586 * uniform(), length = 0.002 + 0.03 * uniform();
        double cx = 0.06 * uniform() - 0.03, cy = 0.06 * uniform() - 0.03, c = 0.01, sum = 0.0;
        double x0 = floor(6.0 * uniform() - 3.0) * c, y0 = floor(6.0 * uniform() - 3.0) * c;
        int i, j;
        double exact = cell_overlap(x0, y0, c, cx, cy, cos(yaw), sin(yaw), length, 0.06);
        double brute = brute_overlap(x0, y0, c, cx, cy, cos(yaw), sin(yaw), length, 0.06);
        if (fabs(exact - brute) > worst_overlap) worst_overlap = fabs(exact - brute);
        for (i = -8; i < 8; i++)
            for (j = -8; j < 8; j++)
                sum += cell_overlap(i * c, j * c, c, cx, cy, cos(yaw), sin(yaw), length, 0.06);
        sum = fabs(sum * c * c / (length * 0.06) - 1.0);
        if (sum > worst_sum) worst_sum = sum;
    }
    /* 2. a pressed half-plane at any angle and offset, stored as cell fractions: points of the
     * middle cell classified by its edge line as the half-plane does */
    soil_grid_init(&g, 0.0, 0.0, 0.07, 0.07, 0.01);
    for (t = 0; t < 400; t++) {
        double angle = 6.283185307179586 * uniform(), nx = cos(angle), ny = sin(angle);
        double px0 = 0.03 + 0.01 * uniform(), py0 = 0.03 + 0.01 * uniform(), f;
        long i, j;
        EdgeLine line;
        for (j = 0; j < g.ny; j++)
            for (i = 0; i < g.nx; i++) {
                long cell = j * g.nx + i;
                /* the cell's share of the half-plane n . (p - p0) <= 0 */
                double base = nx * (i * 0.01 - px0) + ny * (j * 0.01 - py0);
                g.coverage[cell] = (float)square_below(nx, ny, -base / 0.01);
                g.sinkage[cell] = 0.001f * g.coverage[cell];
                g.owner[cell] = g.coverage[cell] > 0.0f;
            }
        f = g.coverage[3 * g.nx + 3];
        if (f <= 1e-6 || f >= 1.0 - 1e-6) continue;
        edge_line(&g, 3, 3, f, 2, 0.0, 0.0, &line);
        for (k = 0; k < 400; k++) {
            double u = ((k % 20) + 0.5) / 20.0, v = ((k / 20) + 0.5) / 20.0;
            double x = (3.0 + u) * 0.01, y = (3.0 + v) * 0.01;
            int truth = nx * (x - px0) + ny * (y - py0) <= 0.0;
            total++;
            wrong += edge_side(&line, u, v) != truth;
        }
    }
    soil_grid_free(&g);
    printf("overlap %.6f\nsum %.3g\nmisclassified %.6f\n", worst_overlap, worst_sum,
           (double)wrong / (double)total);
    return 0;
}
