/* smc_loop.c: the fixed-rate loop of the sliding-mode pose tracker [SMC V-VI], around the generated
 * step kernel smc_step() of the module smc (smc.h / smc.c, built by gagen.control.smc.build through
 * gagen's build pipeline). Compiled with the module's C, -DSMC_LOOP_Q0=a,b,... (the default start,
 * one number per joint) and -DSMC_LOOP_LOWER=... / -DSMC_LOOP_UPPER=... (the joint limits, INFINITY
 * where a joint has none).
 *
 * Every tick k (nominal time t_k = k dt, dt = 1 / rate):
 *   x_ref(t_k)                       the paper's reference [SMC Eq. 43]
 *   smc_step(q, x_ref) -> x, J, u    pose, its Jacobian, u = -K J+ tanh(eps (x - x_ref)) [Eq. 35, 40]
 *                                    with the joint-limit avoidance and velocity bound
 *   q = clamp(q + u dt, lower, upper)  kinematic (explicit Euler) integration of q' = u against the
 *                                    joints' hard stops
 * The reference and the integration use the nominal t_k, never the clock, so the logged trajectory
 * is deterministic: it does not depend on how late a tick ran (the Python `simulate` reproduces it).
 *
 * Real time: ticks are released at absolute times start + k dt on CLOCK_MONOTONIC (clock_nanosleep
 * with TIMER_ABSTIME, so errors do not accumulate). A late tick is not skipped: the schedule is kept
 * and the next release is simply already due. On Linux the timer slack is set to 1 ns (the default
 * 50 us would show as wake-up lateness of a SCHED_OTHER process). Per tick the log holds the start lateness (actual
 * start - release) and the work time (step + integration + logging); a deadline miss is a tick whose
 * lateness + work exceeds the period. The log is kept in memory and written after the loop.
 *
 * Usage: smc_loop [--rate HZ] [--duration S] [--csv PATH] [--transient S] [--q0 a,b,...] [--fifo]
 *        smc_loop --bench STEPS [--repeats R]      (steps per second, no sleeping)
 * Prints a summary as key=value lines on stdout.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif

#include "smc.h"

#define N SMC_STEP_Q_SIZE     /* joints */
#define K SMC_STEP_X_REF_SIZE /* pose coordinates: point (3), line direction (3) */
#if K != 6
#error "the reference trajectory [SMC Eq. 43] is a 6-vector pose"
#endif
#if SMC_STEP_X_SIZE != K || SMC_STEP_U_SIZE != N || SMC_STEP_J_SIZE != K * N
#error "smc_step: expected x[K], J[K*N], u[N]"
#endif
#ifndef SMC_LOOP_Q0
#error "compile with -DSMC_LOOP_Q0=a,b,... (the start, one value per joint)"
#endif
#if !defined(SMC_LOOP_LOWER) || !defined(SMC_LOOP_UPPER)
#error "compile with -DSMC_LOOP_LOWER=a,b,... and -DSMC_LOOP_UPPER=a,b,... (the joint limits)"
#endif

/* per-tick log row: t, q[N], x[K], x_ref[K], u[N], position error, direction error, max |s|,
 * lateness, work */
#define COLS (1 + N + K + K + N + 5)

static const double Q0[N] = {SMC_LOOP_Q0};
static const double LOWER[N] = {SMC_LOOP_LOWER}, UPPER[N] = {SMC_LOOP_UPPER};

/* q += u dt against the hard stops: q never leaves [LOWER, UPPER], whatever u. At rates of at least the
 * step's LIMIT_RATE its velocity bound already keeps q inside and this changes nothing; the Python
 * `simulate` does the same (np.minimum(np.maximum(...)), which also passes a NaN through). Comparisons,
 * not fmin/fmax: those are libm calls here, and after the step's AVX code their SSE encoding doubled
 * the cost of a tick. */
static void integrate(double *q, const double *u, double dt) {
  for (int i = 0; i < N; i++) {
    double v = q[i] + u[i] * dt;
    q[i] = v < LOWER[i] ? LOWER[i] : (v > UPPER[i] ? UPPER[i] : v);
  }
}

/* [SMC Eq. 43]: x_ref = [-0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0] (point, then line direction) */
static void reference(double t, double *xr) {
  xr[0] = -0.3 + 0.1 * cos(2.0 * t);
  xr[1] = 0.15;
  xr[2] = 0.25;
  xr[3] = 0.0;
  xr[4] = 1.0;
  xr[5] = 0.0;
}

static double seconds(const struct timespec *a) { return (double)a->tv_sec + 1e-9 * (double)a->tv_nsec; }

static double since(const struct timespec *a, const struct timespec *b) { /* b - a, in seconds */
  return (double)(b->tv_sec - a->tv_sec) + 1e-9 * (double)(b->tv_nsec - a->tv_nsec);
}

static void advance(struct timespec *t, long ns) {
  t->tv_nsec += ns;
  while (t->tv_nsec >= 1000000000L) {
    t->tv_nsec -= 1000000000L;
    t->tv_sec += 1;
  }
}

static int compare(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void usage(void) {
  fprintf(stderr, "usage: smc_loop [--rate HZ] [--duration S] [--csv PATH] [--transient S] "
                  "[--q0 a,b,...] [--fifo] | --bench STEPS [--repeats R]\n");
}

static int parse_q0(const char *text, double *q) {
  char *end;
  for (int i = 0; i < N; i++) {
    q[i] = strtod(text, &end);
    if (end == text) return -1;
    text = end;
    if (i < N - 1) {
      if (*text != ',') return -1;
      text++;
    }
  }
  return *text == '\0' ? 0 : -1;
}

/* steps per second of step + integration in a tight loop (the median over repeats) */
static int bench(long steps, int repeats) {
  double q[N], xr[K], x[K], J[K * N], u[N];
  double *rates = malloc(sizeof(double) * (size_t)repeats);
  const double dt = 1e-3;
  if (!rates) return 1;
  for (int r = 0; r < repeats; r++) {
    struct timespec a, b;
    memcpy(q, Q0, sizeof q);
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long k = 0; k < steps; k++) {
      reference((double)(k % 1000) * dt, xr);
      smc_step(q, xr, x, J, u);
      integrate(q, u, dt);
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    rates[r] = (double)steps / since(&a, &b);
  }
  qsort(rates, (size_t)repeats, sizeof(double), compare);
  double median = rates[repeats / 2];
  printf("steps=%ld\nrepeats=%d\nsteps_per_second=%.6g\nns_per_step=%.6g\nsteps_per_second_min=%.6g\n"
         "steps_per_second_max=%.6g\ncheck=%.17g\n",
         steps, repeats, median, 1e9 / median, rates[0], rates[repeats - 1], q[0]);
  free(rates);
  return 0;
}

int main(int argc, char **argv) {
  double rate = 1000.0, duration = 10.0, transient = 0.5;
  const char *csv = NULL;
  long bench_steps = 0;
  int repeats = 21, fifo = 0;
  double q[N];
  memcpy(q, Q0, sizeof q);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    int more = i + 1 < argc;
    if (!strcmp(a, "--rate") && more) rate = atof(argv[++i]);
    else if (!strcmp(a, "--duration") && more) duration = atof(argv[++i]);
    else if (!strcmp(a, "--transient") && more) transient = atof(argv[++i]);
    else if (!strcmp(a, "--csv") && more) csv = argv[++i];
    else if (!strcmp(a, "--bench") && more) bench_steps = atol(argv[++i]);
    else if (!strcmp(a, "--repeats") && more) repeats = atoi(argv[++i]);
    else if (!strcmp(a, "--fifo")) fifo = 1;
    else if (!strcmp(a, "--q0") && more) {
      if (parse_q0(argv[++i], q)) {
        fprintf(stderr, "smc_loop: --q0 needs %d comma-separated numbers\n", N);
        return 2;
      }
    } else {
      usage();
      return 2;
    }
  }
  if (bench_steps > 0) return bench(bench_steps, repeats < 1 ? 1 : repeats);
  if (!(rate > 0) || !(duration > 0) || !isfinite(rate) || !isfinite(duration)) {
    usage();
    return 2;
  }
  if (llround(duration * rate) < 1) { /* 0 ticks: nothing to log or summarise */
    fprintf(stderr, "smc_loop: --duration %g s at --rate %g Hz is less than one tick\n", duration, rate);
    return 2;
  }

  const double dt = 1.0 / rate;
  const long period_ns = (long)llround(1e9 / rate);
  const long ticks = (long)llround(duration * rate);
  double *log = calloc((size_t)ticks * COLS, sizeof(double));
  if (!log) {
    fprintf(stderr, "smc_loop: cannot allocate the log (%ld ticks)\n", ticks);
    return 1;
  }
  const char *scheduler = "SCHED_OTHER";
#if defined(__linux__) && defined(PR_SET_TIMERSLACK)
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL); /* wake at the release, not up to 50 us after it */
#endif
  if (fifo) { /* best effort: needs CAP_SYS_NICE (and memory locking CAP_IPC_LOCK or a limit) */
    struct sched_param sp = {.sched_priority = 80};
    if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) scheduler = "SCHED_FIFO";
    else fprintf(stderr, "smc_loop: SCHED_FIFO refused (%s), running SCHED_OTHER\n", strerror(errno));
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
      fprintf(stderr, "smc_loop: mlockall refused (%s)\n", strerror(errno));
  }
  /* touch the log and warm the kernel before the first release */
  for (long k = 0; k < ticks; k++) log[k * COLS] = 0.0;
  {
    double xr[K], x[K], J[K * N], u[N];
    reference(0.0, xr);
    smc_step(q, xr, x, J, u);
  }

  struct timespec release, now, done, first_start = {0}, last_start = {0};
  clock_gettime(CLOCK_MONOTONIC, &release);
  advance(&release, period_ns);
  for (long k = 0; k < ticks; k++) {
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &release, NULL) == EINTR) {
    }
    clock_gettime(CLOCK_MONOTONIC, &now);
    double *row = log + k * COLS;
    const double t = (double)k * dt;
    double xr[K], x[K], J[K * N], u[N];
    reference(t, xr);
    smc_step(q, xr, x, J, u);
    row[0] = t;
    memcpy(row + 1, q, sizeof(double) * N);
    memcpy(row + 1 + N, x, sizeof(double) * K);
    memcpy(row + 1 + N + K, xr, sizeof(double) * K);
    memcpy(row + 1 + N + 2 * K, u, sizeof(double) * N);
    double ep = 0.0, ed = 0.0, es = 0.0;
    for (int i = 0; i < K; i++) {
      double s = x[i] - xr[i];
      if (i < 3) ep += s * s;
      else ed += s * s;
      if (fabs(s) > es) es = fabs(s);
    }
    integrate(q, u, dt);
    row[1 + 2 * N + 2 * K] = sqrt(ep);
    row[2 + 2 * N + 2 * K] = sqrt(ed);
    row[3 + 2 * N + 2 * K] = es;
    row[4 + 2 * N + 2 * K] = since(&release, &now);
    clock_gettime(CLOCK_MONOTONIC, &done);
    row[5 + 2 * N + 2 * K] = since(&now, &done);
    if (k == 0) first_start = now;
    last_start = now;
    advance(&release, period_ns);
  }

  /* summary */
  long misses = 0;
  double late_sum = 0.0, late_sq = 0.0, late_max = 0.0, work_sum = 0.0, work_max = 0.0;
  double err_max = 0.0, pos_max = 0.0, dir_max = 0.0, err_sq = 0.0;
  long settled = 0;
  for (long k = 0; k < ticks; k++) {
    const double *row = log + k * COLS;
    double late = row[4 + 2 * N + 2 * K], work = row[5 + 2 * N + 2 * K];
    late_sum += late;
    late_sq += late * late;
    if (late > late_max) late_max = late;
    work_sum += work;
    if (work > work_max) work_max = work;
    if (late + work > dt) misses++;
    if (row[0] >= transient) {
      settled++;
      if (row[3 + 2 * N + 2 * K] > err_max) err_max = row[3 + 2 * N + 2 * K];
      if (row[1 + 2 * N + 2 * K] > pos_max) pos_max = row[1 + 2 * N + 2 * K];
      if (row[2 + 2 * N + 2 * K] > dir_max) dir_max = row[2 + 2 * N + 2 * K];
      for (int i = 0; i < K; i++) {
        double s = row[1 + N + i] - row[1 + N + K + i];
        err_sq += s * s;
      }
    }
  }
  double late_mean = late_sum / (double)ticks;
  double late_var = late_sq / (double)ticks - late_mean * late_mean;
  double wall = since(&first_start, &last_start);
  printf("scheduler=%s\nrate_hz=%.17g\nduration_s=%.17g\nticks=%ld\nwall_s=%.9f\n", scheduler, rate, duration,
         ticks, wall);
  printf("achieved_rate_hz=%.9g\ndeadline_misses=%ld\n", ticks > 1 ? (double)(ticks - 1) / wall : 0.0, misses);
  printf("jitter_mean_us=%.6g\njitter_std_us=%.6g\njitter_max_us=%.6g\n", 1e6 * late_mean,
         1e6 * sqrt(late_var > 0 ? late_var : 0.0), 1e6 * late_max);
  printf("work_mean_us=%.6g\nwork_max_us=%.6g\n", 1e6 * work_sum / (double)ticks, 1e6 * work_max);
  printf("transient_s=%.17g\nsettled_ticks=%ld\n", transient, settled);
  printf("error_max=%.9g\nerror_rms=%.9g\nposition_error_max=%.9g\ndirection_error_max=%.9g\n", err_max,
         settled ? sqrt(err_sq / (double)(settled * K)) : 0.0, pos_max, dir_max);
  printf("final_q=");
  for (int i = 0; i < N; i++) printf(i ? ",%.17g" : "%.17g", q[i]);
  printf("\nstart_s=%.9f\n", seconds(&first_start));

  if (csv) {
    FILE *f = fopen(csv, "w");
    if (!f) {
      fprintf(stderr, "smc_loop: cannot write %s: %s\n", csv, strerror(errno));
      free(log);
      return 1;
    }
    fprintf(f, "t");
    for (int i = 0; i < N; i++) fprintf(f, ",q%d", i + 1);
    static const char *pose[6] = {"px", "py", "pz", "dx", "dy", "dz"};
    for (int i = 0; i < K; i++) fprintf(f, ",%s", pose[i]);
    for (int i = 0; i < K; i++) fprintf(f, ",ref_%s", pose[i]);
    for (int i = 0; i < N; i++) fprintf(f, ",u%d", i + 1);
    fprintf(f, ",position_error,direction_error,error_max,lateness,work\n");
    for (long k = 0; k < ticks; k++) {
      const double *row = log + k * COLS;
      for (int c = 0; c < COLS; c++) fprintf(f, c ? ",%.17g" : "%.17g", row[c]);
      fputc('\n', f);
    }
    if (fclose(f) != 0) {
      fprintf(stderr, "smc_loop: error writing %s\n", csv);
      free(log);
      return 1;
    }
  }
  free(log);
  return 0;
}
