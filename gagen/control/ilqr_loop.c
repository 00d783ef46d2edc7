/* The structured iLQR loop of gagen.control.ilqr in C: projected Gauss-Newton on the terminal
 * configuration q_N with the exact least-effort LQ subproblem (see ilqr.py's docstring), an Armijo line
 * search on the clipped point, and multiplier updates of the terminal shift s until |e(q_N)| <= tol.
 *
 * The generated task kernel (q, V_Sd) -> (e[7], J_Be[7 x m], column-major) is called through a function
 * pointer: any module's <system>_task. Reentrant: every buffer is the caller's or on the stack (m <= 128).
 * Python computes a, c (the Gramian's quadratic), the trajectory from q_N, and checks the arguments. */
#include <math.h>
#include <string.h>

#define GAGEN_ILQR_MAX_DOF 128
#define ROWS 7

typedef void (*gagen_task_fn)(const double *q, const double *V_Sd, double *e, double *J);

enum { CONVERGED = 0, MAX_ITERATIONS = 1, LINE_SEARCH_FAILED = 2, NON_FINITE = 4, TOO_LARGE = 5 };

static double cost_at(gagen_task_fn task, int m, const double *q, const double *a, const double *c,
                      const double *Q, const double *V_Sd, const double *shift, double *e, double *J) {
    task(q, V_Sd, e, J);
    double total = 0.0, r[ROWS];
    for (int j = 0; j < m; ++j) total += a[j] * (q[j] - c[j]) * (q[j] - c[j]);
    for (int i = 0; i < ROWS; ++i) r[i] = e[i] - shift[i];
    for (int i = 0; i < ROWS; ++i)
        for (int k = 0; k < ROWS; ++k) total += r[i] * Q[i + ROWS * k] * r[k];
    return total;
}

/* Solve S y = b in place (S 7 x 7 symmetric positive definite, overwritten by its Cholesky factor);
 * returns 0 when S is not positive definite. */
static int cholesky_solve(double *S, double *b) {
    for (int j = 0; j < ROWS; ++j) {
        double d = S[j + ROWS * j];
        for (int k = 0; k < j; ++k) d -= S[j + ROWS * k] * S[j + ROWS * k];
        if (!(d > 0.0)) return 0;
        d = sqrt(d);
        S[j + ROWS * j] = d;
        for (int i = j + 1; i < ROWS; ++i) {
            double s = S[i + ROWS * j];
            for (int k = 0; k < j; ++k) s -= S[i + ROWS * k] * S[j + ROWS * k];
            S[i + ROWS * j] = s / d;
        }
    }
    for (int i = 0; i < ROWS; ++i) {  /* L z = b */
        double s = b[i];
        for (int k = 0; k < i; ++k) s -= S[i + ROWS * k] * b[k];
        b[i] = s / S[i + ROWS * i];
    }
    for (int i = ROWS - 1; i >= 0; --i) {  /* Lᵀ y = z */
        double s = b[i];
        for (int k = i + 1; k < ROWS; ++k) s -= S[k + ROWS * i] * b[k];
        b[i] = s / S[i + ROWS * i];
    }
    return 1;
}

/* stats[0] iterations, stats[1] updates, stats[2] status; q_N and shift in and out, e out. */
int gagen_ilqr_solve(gagen_task_fn task, int m, const double *a, const double *c, const double *Q,
                     const double *Q_inverse, const double *V_Sd, const double *lower, const double *upper,
                     double tol, double inner_tol, double stall, double armijo, double min_step,
                     int max_iterations, int max_updates, double *qN, double *shift, double *e, int *stats) {
    if (m > GAGEN_ILQR_MAX_DOF || m < 1) {
        stats[0] = stats[1] = 0;
        stats[2] = TOO_LARGE;
        return TOO_LARGE;
    }
    double J[ROWS * GAGEN_ILQR_MAX_DOF], trial[GAGEN_ILQR_MAX_DOF], trial_e[ROWS];
    double trial_J[ROWS * GAGEN_ILQR_MAX_DOF], gradient[GAGEN_ILQR_MAX_DOF], step[GAGEN_ILQR_MAX_DOF];
    int fixed[GAGEN_ILQR_MAX_DOF];
    int iterations = 0, updates = 0, status = CONVERGED;
    double cost = cost_at(task, m, qN, a, c, Q, V_Sd, shift, e, J);
    for (;;) {
        int stopped = 0;  /* the inner loop ended by a break, not by running out of iterations */
        while (iterations < max_iterations) {
            double Qr[ROWS], r[ROWS];
            for (int i = 0; i < ROWS; ++i) r[i] = e[i] - shift[i];
            for (int i = 0; i < ROWS; ++i) {
                Qr[i] = 0.0;
                for (int k = 0; k < ROWS; ++k) Qr[i] += Q[i + ROWS * k] * r[k];
            }
            double free_norm = 0.0;
            for (int j = 0; j < m; ++j) {
                double g = a[j] * (qN[j] - c[j]);
                for (int i = 0; i < ROWS; ++i) g += J[i + ROWS * j] * Qr[i];
                gradient[j] = g;
                fixed[j] = (qN[j] <= lower[j] && g > 0.0) || (qN[j] >= upper[j] && g < 0.0);
                if (!fixed[j]) free_norm += g * g;
            }
            /* Woodbury: (D + JᵀQJ)⁻¹ g = D⁻¹g − D⁻¹Jᵀ (Q⁻¹ + J D⁻¹ Jᵀ)⁻¹ J D⁻¹ g on the free joints */
            double S[ROWS * ROWS], y[ROWS];
            memcpy(S, Q_inverse, sizeof S);
            for (int i = 0; i < ROWS; ++i) y[i] = 0.0;
            for (int j = 0; j < m; ++j) {
                if (fixed[j]) continue;
                const double *col = J + ROWS * j;
                for (int i = 0; i < ROWS; ++i) {
                    y[i] += col[i] * gradient[j] / a[j];
                    for (int k = 0; k <= i; ++k) S[i + ROWS * k] += col[i] * col[k] / a[j];
                }
            }
            for (int i = 0; i < ROWS; ++i)
                for (int k = i + 1; k < ROWS; ++k) S[i + ROWS * k] = S[k + ROWS * i];
            if (!cholesky_solve(S, y)) {
                status = NON_FINITE;
                stopped = 1;
                break;
            }
            int finite = 1;
            for (int j = 0; j < m; ++j) {
                if (fixed[j]) {
                    step[j] = 0.0;
                    continue;
                }
                double s = gradient[j] / a[j];
                for (int i = 0; i < ROWS; ++i) s -= J[i + ROWS * j] * y[i] / a[j];
                step[j] = -s;
                finite = finite && isfinite(step[j]);
            }
            if (!finite) {
                status = NON_FINITE;
                stopped = 1;
                break;
            }
            ++iterations;
            double length = 1.0, trial_cost = 0.0;
            int accepted = 0;
            while (length >= min_step) {
                double slope = 0.0;
                for (int j = 0; j < m; ++j) {
                    double x = qN[j] + length * step[j];
                    trial[j] = x < lower[j] ? lower[j] : (x > upper[j] ? upper[j] : x);
                    slope += gradient[j] * (trial[j] - qN[j]);
                }
                trial_cost = cost_at(task, m, trial, a, c, Q, V_Sd, shift, trial_e, trial_J);
                if (isfinite(trial_cost) && trial_cost <= cost + armijo * 2.0 * slope) {
                    accepted = 1;
                    break;
                }
                length *= 0.5;
            }
            if (!accepted) {
                if (sqrt(free_norm) > inner_tol) status = LINE_SEARCH_FAILED;
                stopped = 1;
                break;
            }
            double moved = 0.0, largest = 1.0;
            for (int j = 0; j < m; ++j) {
                double d = fabs(trial[j] - qN[j]);
                moved = d > moved ? d : moved;
                largest = fabs(trial[j]) > largest ? fabs(trial[j]) : largest;
            }
            double decrease = cost - trial_cost;
            memcpy(qN, trial, sizeof(double) * (size_t)m);
            memcpy(e, trial_e, sizeof trial_e);
            memcpy(J, trial_J, sizeof(double) * ROWS * (size_t)m);
            cost = trial_cost;
            if (moved <= inner_tol * largest || decrease <= stall * cost) {
                stopped = 1;
                break;
            }
        }
        if (!stopped) status = MAX_ITERATIONS;
        double norm = 0.0;
        for (int i = 0; i < ROWS; ++i) norm += e[i] * e[i];
        if (status != CONVERGED || sqrt(norm) <= tol || updates >= max_updates) break;
        for (int i = 0; i < ROWS; ++i) shift[i] -= e[i];
        ++updates;
        cost = cost_at(task, m, qN, a, c, Q, V_Sd, shift, e, J);
    }
    stats[0] = iterations;
    stats[1] = updates;
    stats[2] = status;
    return status;
}
