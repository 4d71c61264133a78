/* Terrain: DEM heightmap and rigid rocks read from a terrain file (docs/terrain-format.md). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "idefix.h"

#define NO_ROCK (-1e300)

/* A wheel's contact with a rock is asked for several times at the same place: a step checks
 * the wheels' new places for rock faces (contact.c) and then sets the wheels on them, with the
 * same arguments to the bit. rock_wheel_centre is a pure function of the rock and its
 * arguments, so it keeps its recent answers, found by the arguments' bits (a direct-mapped
 * table: a newer answer replaces an older one in its slot). An answer is returned only for
 * arguments equal to those it was computed for, so the cache never changes a result's bits;
 * it lives with the rocks (a new terrain starts empty). */
#define ROCK_CONTACTS 256

typedef struct RockContact {
    double x, y, hx, hy, r, w;   /* the arguments */
    double centre, d, z;         /* the answer */
    int k;                       /* the rock, -1 for an empty slot */
} RockContact;

void terrain_free(Terrain *t)
{
    free(t->height);
    free(t->rocks);
    free(t->contacts);
    free(t->path);
    memset(t, 0, sizeof(*t));
}

static int fail(char *message, size_t size, const char *path, int line, const char *what)
{
    snprintf(message, size, "%s:%d: %s", path, line, what);
    return -1;
}

/* FNV-1a over the whole file: cheap against parsing it (terrain files are a few MB at most). */
static unsigned long long content_hash(FILE *f)
{
    unsigned char buffer[65536];
    unsigned long long h = 14695981039346656037ULL;
    size_t n, k;
    while ((n = fread(buffer, 1, sizeof(buffer), f)) > 0)
        for (k = 0; k < n; k++) h = (h ^ buffer[k]) * 1099511628211ULL;
    return h;
}

static int read_line(FILE *f, char *buffer, int size, int *line)
{
    if (!fgets(buffer, size, f)) return 0;
    (*line)++;
    return 1;
}

int terrain_load(Terrain *t, const char *path, char *message, size_t message_size)
{
    struct stat info;
    char line_text[512];
    int line = 0;
    long nx = 0, ny = 0, n_rocks = 0, i;
    double x0 = 0.0, y0 = 0.0, cell = 0.0;
    FILE *f;
    Terrain fresh;
    unsigned long long hash;

    if (path == NULL || path[0] == '\0') {
        terrain_free(t);
        return 0;
    }
    if (stat(path, &info) != 0) return fail(message, message_size, path, 0, "cannot open");
    f = fopen(path, "rb");
    if (!f) return fail(message, message_size, path, 0, "cannot open");
    /* Cached across resets while the file's bytes are unchanged: keyed by path and a hash of
     * the content (a replaced file with a preserved modification time is read again). */
    hash = content_hash(f);
    if (t->loaded && t->path && strcmp(t->path, path) == 0 && t->hash == hash) {
        fclose(f);
        return 0;
    }
    rewind(f);
    memset(&fresh, 0, sizeof(fresh));
    if (!read_line(f, line_text, sizeof(line_text), &line) ||
        strncmp(line_text, "IDEFIX-TERRAIN 1", 16) != 0) {
        fclose(f);
        return fail(message, message_size, path, 1, "expected header 'IDEFIX-TERRAIN 1'");
    }
    for (;;) {
        char key[32];
        if (!read_line(f, line_text, sizeof(line_text), &line)) {
            fclose(f);
            free(fresh.rocks);
            return fail(message, message_size, path, line, "missing 'heights' line");
        }
        if (sscanf(line_text, "%31s", key) != 1) continue;
        if (strcmp(key, "nx") == 0 && sscanf(line_text, "%*s %ld", &nx) == 1) continue;
        if (strcmp(key, "ny") == 0 && sscanf(line_text, "%*s %ld", &ny) == 1) continue;
        if (strcmp(key, "origin") == 0 && sscanf(line_text, "%*s %lf %lf", &x0, &y0) == 2) continue;
        if (strcmp(key, "cell") == 0 && sscanf(line_text, "%*s %lf", &cell) == 1) continue;
        if (strcmp(key, "rocks") == 0 && sscanf(line_text, "%*s %ld", &n_rocks) == 1) {
            if (n_rocks < 0 || n_rocks > MAX_ROCKS || fresh.rocks) {
                fclose(f);
                return fail(message, message_size, path, line, "bad rock count");
            }
            fresh.rocks = (Rock *)calloc((size_t)(n_rocks > 0 ? n_rocks : 1), sizeof(Rock));
            for (i = 0; i < n_rocks; i++) {
                Rock *r = &fresh.rocks[i];
                if (!read_line(f, line_text, sizeof(line_text), &line) ||
                    sscanf(line_text, "rock %lf %lf %lf %lf %lf %lf", &r->x, &r->y, &r->z, &r->a,
                           &r->b, &r->c) != 6 || r->a <= 0 || r->b <= 0 || r->c <= 0) {
                    fclose(f);
                    free(fresh.rocks);
                    return fail(message, message_size, path, line,
                                "expected 'rock x y z a b c' with positive semi-axes");
                }
            }
            fresh.n_rocks = (int)n_rocks;
            continue;
        }
        if (strcmp(key, "heights") == 0) break;
        fclose(f);
        free(fresh.rocks);
        return fail(message, message_size, path, line, "unknown or malformed header line");
    }
    if (nx < 2 || ny < 2 || !(cell > 0.0) || !isfinite(cell) || !isfinite(x0) ||
        !isfinite(y0) || nx > 16000000L || ny > 16000000L || nx * ny > 16000000L) {
        fclose(f);
        free(fresh.rocks);
        return fail(message, message_size, path, line, "need nx >= 2, ny >= 2, cell > 0");
    }
    fresh.height = (double *)malloc((size_t)(nx * ny) * sizeof(double));
    if (!fresh.height || fread(fresh.height, sizeof(double), (size_t)(nx * ny), f) !=
                             (size_t)(nx * ny)) {
        fclose(f);
        free(fresh.height);
        free(fresh.rocks);
        return fail(message, message_size, path, line, "height grid shorter than nx*ny doubles");
    }
    fclose(f);
    for (i = 0; i < nx * ny; i++) {
        if (!isfinite(fresh.height[i])) {
            free(fresh.height);
            free(fresh.rocks);
            return fail(message, message_size, path, line, "height grid holds NaN or inf");
        }
    }
    terrain_free(t);
    *t = fresh;
    t->loaded = 1;
    if (n_rocks > 0) {
        t->contacts = (RockContact *)malloc(ROCK_CONTACTS * sizeof(RockContact));
        if (t->contacts)
            for (i = 0; i < ROCK_CONTACTS; i++) t->contacts[i].k = -1;
    }
    t->nx = nx;
    t->ny = ny;
    t->x0 = x0;
    t->y0 = y0;
    t->cell = cell;
    t->hash = hash;
    t->path = (char *)malloc(strlen(path) + 1);
    if (t->path) strcpy(t->path, path);
    return 0;
}

/* Bilinear interpolation; outside the grid the edge values continue. */
double terrain_height(const Terrain *t, double x, double y)
{
    double fx, fy, tx, ty;
    long i, j;
    const double *h;
    if (!t->loaded) return 0.0;
    fx = (x - t->x0) / t->cell;
    fy = (y - t->y0) / t->cell;
    if (fx < 0.0) fx = 0.0;
    if (fy < 0.0) fy = 0.0;
    if (fx > (double)(t->nx - 1)) fx = (double)(t->nx - 1);
    if (fy > (double)(t->ny - 1)) fy = (double)(t->ny - 1);
    i = (long)fx;
    j = (long)fy;
    if (i > t->nx - 2) i = t->nx - 2;
    if (j > t->ny - 2) j = t->ny - 2;
    tx = fx - (double)i;
    ty = fy - (double)j;
    h = t->height + j * t->nx + i;
    return (1 - ty) * ((1 - tx) * h[0] + tx * h[1]) + ty * ((1 - tx) * h[t->nx] + tx * h[t->nx + 1]);
}

static double top_of(const Rock *r, double x, double y)
{
    double ex = (x - r->x) / r->a, ey = (y - r->y) / r->b, q = ex * ex + ey * ey;
    return q < 1.0 ? r->z + r->c * sqrt(1.0 - q) : NO_ROCK;
}

double rock_top(const Terrain *t, double x, double y)
{
    double best = NO_ROCK;
    int k;
    for (k = 0; k < t->n_rocks; k++) {
        double top = top_of(&t->rocks[k], x, y);
        if (top > best) best = top;
    }
    return best;
}

/* The wheel is a cylinder of radius r and width w, its axis horizontal and across the heading
 * (hx, hy). Over a rock its centre must sit at
 *     H = max over the footprint (d along, e across) of [top(p(d, e)) + sqrt(r^2 - d^2)],
 * the envelope of the wheel rolling over the rock. For an ellipsoid the top is concave on its
 * ellipse (z_c + c sqrt(1 - q), q a convex quadratic in (d, e)) and sqrt(r^2 - d^2) is concave,
 * so the maximum is unique: for each d the best e minimises q (analytic, clamped to the width),
 * and the remaining concave function of d is maximised by golden-section search on the interval
 * of d where the rock is under the footprint. Exact up to SEARCH_TOLERANCE, for rocks of any
 * size; every rock within reach is considered. */
#define SEARCH_TOLERANCE 1e-7  /* m, of the contact position along the wheel */

typedef struct {
    double q0, qd, qe, qdd, qde, qee;  /* q(d, e) = q0 + qd d + qe e + qdd d^2 + qde d e + qee e^2 */
    double half_width;
} Footprint;

/* q of the ellipse at (d, e) with e chosen to minimise q within the wheel width. */
static double q_best(const Footprint *f, double d, double *e_best)
{
    double e = -(f->qe + f->qde * d) / (2.0 * f->qee);
    if (e > f->half_width) e = f->half_width;
    if (e < -f->half_width) e = -f->half_width;
    *e_best = e;
    return f->q0 + f->qd * d + f->qe * e + f->qdd * d * d + f->qde * d * e + f->qee * e * e;
}

static double envelope(const Rock *rk, const Footprint *f, double r, double d, double *top)
{
    double e, q = q_best(f, d, &e);
    *top = rk->z + rk->c * sqrt(q < 1.0 ? 1.0 - q : 0.0);
    return *top + sqrt(fmax(r * r - d * d, 0.0));
}

static const double GOLDEN = 0.6180339887498949;

/* One rock: the wheel-centre height it asks for, or NO_ROCK if it is not under the wheel. */
static double rock_envelope(const Rock *rk, double x, double y, double hx, double hy, double r,
                            double w, double *contact_d, double *contact_z)
{
    /* p(d, e) = (x, y) + d (hx, hy) + e (-hy, hx); u = (p - centre) / axes */
    double ux = (x - rk->x) / rk->a, uy = (y - rk->y) / rk->b;
    double dx = hx / rk->a, dy = hy / rk->b, ex = -hy / rk->a, ey = hx / rk->b;
    Footprint f;
    double lo = -r, hi = r, a, b, m1, m2, t1, t2, top, best;
    int k;
    f.q0 = ux * ux + uy * uy;
    f.qd = 2.0 * (ux * dx + uy * dy);
    f.qe = 2.0 * (ux * ex + uy * ey);
    f.qdd = dx * dx + dy * dy;
    f.qde = 2.0 * (dx * ex + dy * ey);
    f.qee = ex * ex + ey * ey;
    f.half_width = 0.5 * w;
    /* the d of smallest q (convex in d): is the rock under the footprint at all? */
    a = lo;
    b = hi;
    for (k = 0; k < 200 && b - a > SEARCH_TOLERANCE; k++) {
        double e;
        m1 = b - GOLDEN * (b - a);
        m2 = a + GOLDEN * (b - a);
        if (q_best(&f, m1, &e) < q_best(&f, m2, &e)) b = m2;
        else a = m1;
    }
    {
        double e, centre = 0.5 * (a + b);
        if (q_best(&f, centre, &e) >= 1.0) return NO_ROCK;
        /* the interval of d where q < 1, by bisection on each side */
        if (q_best(&f, lo, &e) >= 1.0) {
            double inside = centre, outside = lo;
            for (k = 0; k < 200 && inside - outside > SEARCH_TOLERANCE; k++) {
                double mid = 0.5 * (inside + outside);
                if (q_best(&f, mid, &e) < 1.0) inside = mid;
                else outside = mid;
            }
            lo = outside;
        }
        if (q_best(&f, hi, &e) >= 1.0) {
            double inside = centre, outside = hi;
            for (k = 0; k < 200 && outside - inside > SEARCH_TOLERANCE; k++) {
                double mid = 0.5 * (inside + outside);
                if (q_best(&f, mid, &e) < 1.0) inside = mid;
                else outside = mid;
            }
            hi = outside;
        }
    }
    /* golden-section search of the concave envelope on [lo, hi] */
    a = lo;
    b = hi;
    m1 = b - GOLDEN * (b - a);
    m2 = a + GOLDEN * (b - a);
    t1 = envelope(rk, &f, r, m1, &top);
    t2 = envelope(rk, &f, r, m2, &top);
    for (k = 0; k < 200 && b - a > SEARCH_TOLERANCE; k++) {
        if (t1 < t2) {
            a = m1;
            m1 = m2;
            t1 = t2;
            m2 = a + GOLDEN * (b - a);
            t2 = envelope(rk, &f, r, m2, &top);
        } else {
            b = m2;
            m2 = m1;
            t2 = t1;
            m1 = b - GOLDEN * (b - a);
            t1 = envelope(rk, &f, r, m1, &top);
        }
    }
    *contact_d = 0.5 * (a + b);
    best = envelope(rk, &f, r, *contact_d, &top);
    *contact_z = top;
    return best;
}

/* The table slot of a rock and a wheel place: a multiplicative hash of the bits. */
static size_t contact_slot(int k, double x, double y, double hx)
{
    uint64_t bx, by, bh, h;
    memcpy(&bx, &x, sizeof(bx));
    memcpy(&by, &y, sizeof(by));
    memcpy(&bh, &hx, sizeof(bh));
    h = ((bx * 0x9E3779B97F4A7C15ULL) ^ (by * 0xC2B2AE3D27D4EB4FULL) ^ bh ^ (uint64_t)k) *
        0x9E3779B97F4A7C15ULL;
    return (size_t)(h >> 56);  /* 8 bits: ROCK_CONTACTS slots */
}

double rock_wheel_centre(const Terrain *t, int k, double x, double y, double hx, double hy,
                         double r, double w, double *contact_d, double *contact_z)
{
    const Rock *rk = &t->rocks[k];
    double reach = sqrt(r * r + 0.25 * w * w), dx = x - rk->x, dy = y - rk->y;
    double big = rk->a > rk->b ? rk->a : rk->b;
    RockContact *slot;
    *contact_d = 0.0;
    *contact_z = NO_ROCK;
    /* rocks are found by a bounding-circle test: every rock within reach counts */
    if (dx * dx + dy * dy >= (big + reach) * (big + reach)) return NO_ROCK;
    if (!t->contacts) return rock_envelope(rk, x, y, hx, hy, r, w, contact_d, contact_z);
    slot = &t->contacts[contact_slot(k, x, y, hx)];
    if (!(slot->k == k && slot->x == x && slot->y == y && slot->hx == hx && slot->hy == hy &&
          slot->r == r && slot->w == w)) {
        double d, z, centre = rock_envelope(rk, x, y, hx, hy, r, w, &d, &z);
        *slot = (RockContact){x, y, hx, hy, r, w, centre, d, z, k};
    }
    *contact_d = slot->d;
    *contact_z = slot->z;
    return slot->centre;
}
