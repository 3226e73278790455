/* K = L D L^T by CHOLMOD's supernodal Cholesky factorisation in a given order
   (app/solvers/ldl.py: Factor, whose numpy reference is ldl_numpy). */
#include <stdlib.h>
#include <string.h>
#include <cholmod.h>

#include "cholmod_ldl.h"

/* The factor and the CHOLMOD workspace it was made in. */
typedef struct { cholmod_common c; cholmod_factor *L; } ldl_handle;

/* Frees the factor and the workspace (NULL: nothing). */
void ldl_free(void *handle)
{
    ldl_handle *h = handle;
    if (!h) return;
    if (h->L) cholmod_free_factor(&h->L, &h->c);
    cholmod_finish(&h->c);
    free(h);
}

/* A (n x n, CSC; only its lower triangle is read: a symmetric CSR matrix is its own CSC)
   = P^T L L^T P, CHOLMOD's supernodal factor, in the given order perm (position j <- dof
   perm[j]).  status: 0 ok, 1 not positive definite, 2 CHOLMOD changed the order,
   3 CHOLMOD failed. */
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 int *status)
{
    ldl_handle *h = calloc(1, sizeof *h);
    *status = 3;
    if (!h) return NULL;
    cholmod_start(&h->c);
    h->c.print = 0;
    h->c.error_handler = NULL;
    h->c.nmethods = 1;
    h->c.method[0].ordering = CHOLMOD_GIVEN;
    h->c.postorder = 0;                       /* keep the given order (Gamma3 last) */
    h->c.supernodal = CHOLMOD_SUPERNODAL;     /* kept as it is: no simplicial copy */
    h->c.final_asis = 1;
    cholmod_sparse A;
    memset(&A, 0, sizeof A);
    A.nrow = A.ncol = n;
    A.nzmax = Ap[n];
    A.p = (void *)Ap; A.i = (void *)Ai; A.x = (void *)Ax;
    A.stype = -1;
    A.itype = CHOLMOD_INT; A.xtype = CHOLMOD_REAL; A.dtype = CHOLMOD_DOUBLE;
    A.sorted = 1; A.packed = 1;
    h->L = cholmod_analyze_p(&A, (int *)perm, NULL, 0, &h->c);
    if (!h->L || h->c.status < CHOLMOD_OK) { ldl_free(h); return NULL; }
    const int *P = h->L->Perm;
    for (int j = 0; j < n; ++j)
        if (P[j] != perm[j]) { *status = 2; ldl_free(h); return NULL; }
    cholmod_factorize(&A, h->L, &h->c);
    if (h->c.status == CHOLMOD_NOT_POSDEF || h->L->minor < (size_t)n) {
        *status = 1; ldl_free(h); return NULL;
    }
    if (h->c.status < CHOLMOD_OK || !h->L->is_super || !h->L->is_ll) {
        ldl_free(h); return NULL;
    }
    *status = 0;
    return h;
}

/* CHOLMOD's value array of the supernodal factor (xsize doubles). */
double *ldl_values(void *handle)
{
    return ((ldl_handle *)handle)->L->x;
}

/* The L D L^T form of the supernodal L L^T (L_ldl = L D^-1/2, D = diag(L)^2): D (n), the
   dense unit lower L_GG of the last m columns (column-major: a column's rows are written
   one after the other), and the first nbc block columns
   (bs columns each) in the block form of ldl_blocks (ldl_blocks.c) (Bp, Bi, Bx, Ld; exact zeros,
   e.g. of CHOLMOD's relaxed supernodes, skipped).  Supernode sn holds the columns
   super[sn] .. super[sn+1]-1 as a dense column-major panel of nsrow = pi[sn+1] - pi[sn]
   rows s[pi[sn]..] (the diagonal block's rows first) at x + px[sn].
   With Bi == NULL it only counts: D, L_GG, Bp[J + 1] = the blocks of column J, and returns
   1 if Bx may be CHOLMOD's own value array (every block column's blocks end before the next
   column's panel starts, so the values are read before they are overwritten), else 0.
   Then the caller makes Bp cumulative, and calls again with Bi (Bx: a new array, or
   ldl_values()).  mark, slot: one int per block row, all -1 on entry.  Returns -1 if out
   of memory. */
int ldl_blocks_super(void *handle, int bs, int nbc, int m, int *Bp, int *Bi, double *Bx,
                     double *Ld, double *D, double *LGG, int *mark, int *slot)
{
    const cholmod_factor *L = ((ldl_handle *)handle)->L;
    const int n = (int)L->n, nsuper = (int)L->nsuper, ni = n - m, b2 = bs * bs;
    const int *super = L->super, *pi = L->pi, *px = L->px, *s = L->s;
    double *x = L->x;
    int *sn_of = malloc((size_t)n * sizeof(int)), maxrow = 0;
    if (!sn_of) return -1;
    for (int sn = 0; sn < nsuper; ++sn) {
        for (int j = super[sn]; j < super[sn + 1]; ++j) sn_of[j] = sn;
        if (pi[sn + 1] - pi[sn] > maxrow) maxrow = pi[sn + 1] - pi[sn];
    }
    /* the block row of each row of the current supernode: one division per row and
       supernode instead of one per entry (a supernode's columns share its rows) */
    int *rI = malloc((size_t)(maxrow > 0 ? maxrow : 1) * sizeof(int)), rI_sn = -1;
    if (!rI) { free(sn_of); return -1; }
#define COLUMN(j, sn, off, nsrow) const int sn = sn_of[j], off = (j) - super[sn],         \
    nsrow = pi[sn + 1] - pi[sn];                                                           \
    if (sn != rI_sn) {                                                                     \
        for (int q_ = 0; q_ < nsrow; ++q_) rI[q_] = s[pi[sn] + q_] / bs;                   \
        rI_sn = sn;                                                                        \
    }
    int in_place = 1;
    if (!Bi) {
        for (int j = 0; j < n; ++j) {                       /* D, L_GG */
            COLUMN(j, sn, off, nsrow);
            const double *v = x + px[sn] + (size_t)off * nsrow;
            const double ljj = v[off];
            D[j] = ljj * ljj;
            if (j >= ni)
                for (int q = off; q < nsrow; ++q)
                    LGG[(size_t)(j - ni) * m + (s[pi[sn] + q] - ni)] = q == off ? 1.0
                                                                       : v[q] / ljj;
        }
        long out = 0;
        for (int J = 0; J < nbc; ++J) {
            int count = 0;
            for (int a = 0; a < bs; ++a) {
                const int j = bs * J + a;
                COLUMN(j, sn, off, nsrow);
                const double *v = x + px[sn] + (size_t)off * nsrow;
                for (int q = off + 1; q < nsrow; ++q) {
                    const int I = rI[q];
                    if (I == J || v[q] == 0.0 || mark[I] == J) continue;
                    mark[I] = J;
                    ++count;
                }
            }
            Bp[J + 1] = count;
            out += (long)count * b2;
            if (bs * (J + 1) < n) {                         /* the next column's panel */
                const int j = bs * (J + 1);
                COLUMN(j, sn, off, nsrow);
                in_place &= out <= (long)px[sn] + (long)off * nsrow;
            }
        }
        free(sn_of); free(rI);
        return in_place;
    }
    /* fill: each block column's values are copied out first (they may be overwritten) */
    double *tv = malloc((size_t)bs * maxrow * sizeof(double)), tl[3];
    int *tr = malloc((size_t)bs * maxrow * sizeof(int)), tn[3];
    int *tI = malloc((size_t)bs * maxrow * sizeof(int));
    if (!tv || !tr || !tI) { free(sn_of); free(rI); free(tv); free(tr); free(tI); return -1; }
    for (int J = 0; J < nbc; ++J) {
        for (int a = 0; a < bs; ++a) {
            const int j = bs * J + a;
            COLUMN(j, sn, off, nsrow);
            const double *v = x + px[sn] + (size_t)off * nsrow;
            tl[a] = v[off];
            tn[a] = nsrow - off - 1;
            for (int q = off + 1; q < nsrow; ++q) {
                tr[a * maxrow + q - off - 1] = s[pi[sn] + q];
                tI[a * maxrow + q - off - 1] = rI[q];
                tv[a * maxrow + q - off - 1] = v[q];
            }
        }
        for (size_t q = (size_t)Bp[J] * b2; q < (size_t)Bp[J + 1] * b2; ++q) Bx[q] = 0.0;
        int count = 0;
        for (int a = 0; a < bs; ++a)
            for (int q = 0; q < tn[a]; ++q) {
                const int i = tr[a * maxrow + q], I = tI[a * maxrow + q], b = i - bs * I;
                const double raw = tv[a * maxrow + q], val = raw / tl[a];
                if (I == J) {                       /* the diagonal block: b > a */
                    Ld[(size_t)J * b2 + a * bs + b] = val;
                    continue;
                }
                if (raw == 0.0) continue;           /* as counted */
                if (mark[I] != J) {
                    mark[I] = J;
                    slot[I] = Bp[J] + count;
                    Bi[Bp[J] + count] = I;
                    ++count;
                }
                Bx[(size_t)slot[I] * b2 + a * bs + b] = val;
            }
    }
#undef COLUMN
    free(sn_of); free(rI); free(tv); free(tr); free(tI);
    return 0;
}

/* A fill-reducing order of a symmetric graph (CSR = CSC, full pattern, sorted; only the
   lower triangle is read): CHOLMOD's own choice (AMD, or METIS nested dissection where AMD
   fills more), postordered along the elimination tree, as cholmod_analyze makes it (perm:
   position j <- vertex perm[j]).  Returns 0, or -1 if CHOLMOD fails (the caller falls back
   to another ordering). */
int metis_order(int n, const int *Ap, const int *Ai, int *perm)
{
    cholmod_common c;
    cholmod_start(&c);
    c.print = 0;
    c.error_handler = NULL;
    cholmod_sparse A;
    memset(&A, 0, sizeof A);
    A.nrow = A.ncol = n;
    A.nzmax = Ap[n];
    A.p = (void *)Ap; A.i = (void *)Ai; A.x = NULL;
    A.stype = -1;
    A.itype = CHOLMOD_INT; A.xtype = CHOLMOD_PATTERN; A.dtype = CHOLMOD_DOUBLE;
    A.sorted = 1; A.packed = 1;
    cholmod_factor *L = cholmod_analyze(&A, &c);
    int bad = !L || c.status < CHOLMOD_OK;
    if (!bad) memcpy(perm, L->Perm, (size_t)n * sizeof(int));
    if (L) cholmod_free_factor(&L, &c);
    cholmod_finish(&c);
    return bad ? -1 : 0;
}
