/* consph run PROBLEM: one WCSPH simulation (include/consph/solver.h), or 002's heat-conduction
 * problem (include/consph/heat.h). */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "commands.h"
#include "consph/gpu.h"
#include "consph/par.h"
#include "consph/heat.h"
#include "consph/io.h"
#include "consph/layout.h"
#include "consph/solver.h"

#define STR_(x) #x
#define STR(x) STR_(x)

static const char run_details[] =
    "Defaults follow 001 (Negi & Ramachandran): quintic spline, h/Δs 1.2, U 1, c_o 10 U,\n"
    "Re 100, RK2 (explicit midpoint), Δt = 0.3 h/(U + c_o), packed particles for the\n"
    "Lagrangian schemes and the lattice for l-rr-c and the Eulerian ones; IPST every 10\n"
    "steps, at most 10 iterations, ε 1e-3. docs/schemes.md records every choice.\n"
    "gresho-chan (001 eq. 37): ν 0, t_f 3, lattice; shear-layer (001 eqs. 38-39): ν 1e-4,\n"
    "t_f 1, lattice, no exact solution (errors n/a); beltrami: the 3D ABC flow on the\n"
    "periodic unit cube (A = B = C = U, k = 2π; nx^3 particles), defaults as taylor-green's;\n"
    "an option given overrides these.\n"
    "\n"
    "With --out DIR: DIR/run.pvd indexing snap_NNNNNN.vtu (every --snapshot-every steps and\n"
    "the last), DIR/log.csv (one row per step), DIR/summary.json, and DIR/checkpoint.ckpt\n"
    "every --checkpoint-every steps; gresho-chan adds DIR/profile.csv (u_φ(r) and the exact\n"
    "one), shear-layer DIR/vorticity.png (with gnuplot; vorticity.gp draws it later).\n"
    "SIGINT/SIGTERM finish the step, write a checkpoint and exit 130/143;\n"
    "--restart DIR/checkpoint.ckpt continues bit for bit (the output\n"
    "options are not in the checkpoint: give --out, --snapshot-every and --checkpoint-every\n"
    "again); with a later --tf or more --steps it continues to that end, equal to the run made\n"
    "with that end from the start (checkpoints are never of a run's last step: a finished run\n"
    "continues from its last multiple of --checkpoint-every); refused for --error authors, whose\n"
    "output times divide the whole run. A DIR holding another run's files is refused: a new run\n"
    "needs --overwrite (which removes those files, nothing else), a restart its own run's DIR\n"
    "(DIR/run.id) or a new one.\n"
    "\n"
    "--particles FILE starts from a CSV or VTU of particles (as consph approx reads them) in\n"
    "the problem's box (a file stating another box or periodicity is refused): positions, and\n"
    "the fields velocity (or u) and pressure (or p) where present, else the problem's solution\n"
    "at t = 0. N particles: nx = N^(1/d) when N is a perfect power (a file of consph layout\n"
    "gives the run of --layout, bit for bit), else Δs = (box volume / N)^(1/d); not with --nx,\n"
    "--layout, --seed. --config FILE reads key = value lines ('#' comments) with the run keys of\n"
    "study files (problem, scheme, nx, tf, ...); the options given replace its keys (--steps\n"
    "its tf, --re its nu, --dt its cfl and h_dt, and back). A bad file: FILE:LINE, exit 2,\n"
    "nothing written. docs/solver-files.md, \"Runs from the user's inputs\".\n"
    "\n"
    "Options that would do nothing are refused: --steps with --tf, --cfl or --h-dt with --dt,\n"
    "--snapshot-every/--checkpoint-every/--overwrite without --out, a scheme parameter the\n"
    "scheme does not read (--alpha: wcsph and the δ-SPH family; --delta: pe-ipst-c, tv-c, e-c\n"
    "and the δ-SPH family; --eos other than default: not pe-ipst-c, tvf, edac; --ipst-*: the\n"
    "IPST schemes), --seed for a layout that draws no random numbers (lattice, quasi-random;\n"
    "the problem's or scheme's default included) and heat's --seed without --eps.\n"
    "\n"
    "--error authors adds 001's own measure (its authors' post-processing, docs/schemes.md):\n"
    "the mean over --error-times N output times in [0, t_f], t = 0 included, of\n"
    "mean||u| - |u_e|| / mean|u_e| and mean|p - p_e| / max|p_e|; with --tf the steps are\n"
    "shortened to land on those times (as PySPH's output_at_times), with --steps K the output\n"
    "times are the ends of steps round(k K/(N - 1)). eq. 26 is printed beside it.\n"
    "\n"
    "consph run heat (002 section 6, docs/heat.md): dT/dt = ∇²T on the unit square,\n"
    "nx × nx particles on the grid vertices (walls included, Δ = 1/(nx - 1)), Dirichlet\n"
    "walls as source-only particles, Wendland C2 with support h = eta Δ, forward Euler with\n"
    "Δt = 0.2 d_min², the last step landing on --tf. Options: --laplacian s3|s4 --nx N\n"
    "--eta H/Δ [--eps E] [--seed S] [--tf T] [--steps K] [--walls sin|linear] [--out DIR]\n"
    "[--snapshot-every K] [--overwrite] [--format table|json] [--threads T]; the others are "
    "WCSPH's.\n"
    "\n"
    /* the bounds are the solver's constants; clang-format would break these lines apart */
    /* clang-format off */
    "A run stops (exit 3) when it leaves the weakly-compressible model: a non-finite value,\n"
    "Mach number |u|/c_o above " STR(CONSPH_VALID_MACH) ", |rhof/rho_o - 1| above "
    STR(CONSPH_VALID_COMPRESSION) " (not for edac,\n"
    "whose p has no EOS), or kinetic energy above (1 + " STR(CONSPH_VALID_KE_GROWTH)
    ") times its initial value (no\n"
    "problem here has an energy source). A Δt above " STR(CONSPH_DT_ACOUSTIC) " h/(U + c_o) or "
    STR(CONSPH_DT_VISCOUS) " h²/ν is\n"
    "warned about. docs/schemes.md, \"Validity of a run\", says why these bounds.\n"
    "\n"
    "exit status: 0 done, 1 failure, 2 bad usage, 3 the run diverged or left the model's\n"
    "validity (the message names the step, t, the particle, its position, the quantity, its\n"
    "value and the bound), 130/143 stopped by a signal";
/* clang-format on */

static int make_dir(const cli_command *cmd, const char *dir)
{
    struct stat st;
    if (stat(dir, &st) == 0) {
        if (!S_ISDIR(st.st_mode))
            return cli_error(cmd, "option --out: '%s' is not a directory", dir);
        return 0;
    }
    if (mkdir(dir, 0777) != 0)
        return cli_error(cmd, "option --out: cannot create directory '%s': %s", dir,
                         strerror(errno));
    return 0;
}

/* --out DIR made, and free of another run's files: those of an earlier run are refused (or, with
 * --overwrite, removed) for a new run (run_id NULL); a restart needs its own run's directory. */
static int prepare_out(const cli_command *cmd, const char *dir, const char *run_id, int overwrite)
{
    /* under MPI rank 0 alone writes the run's files: it alone makes and clears the directory
     * (its failure reaches the other ranks at the agreement before the decomposition) */
    if (consph_par_rank() != 0) return 0;
    int rc = make_dir(cmd, dir);
    if (rc) return rc;
    int st = consph_run_dir_check(dir, run_id, overwrite);
    if (st == CONSPH_OK) return 0;
    if (st == CONSPH_EIO || st == CONSPH_ENOMEM) {
        fprintf(stderr, "consph run: option --out: %s\n", consph_last_error());
        return 1;
    }
    return cli_error(cmd, "option --out: %s%s", consph_last_error(),
                     run_id || st != CONSPH_EINVAL
                         ? ""
                         : "; give --overwrite to remove them (only those), or another directory");
}

/* An error against the exact solution, or n/a where the problem has none (the shear layer). */
static void error_text(char *buf, size_t size, double v)
{
    if (isfinite(v))
        snprintf(buf, size, "%.6e", v);
    else
        snprintf(buf, size, "n/a");
}

/* The options the heat problem shares with the WCSPH runs. */
static int heat_option(const char *name)
{
    static const char *const shared[] = {"--nx",     "--seed",    "--tf",
                                         "--steps",  "--out",     "--snapshot-every",
                                         "--format", "--threads", "--overwrite"};
    for (size_t k = 0; k < sizeof shared / sizeof shared[0]; ++k)
        if (strcmp(name, shared[k]) == 0) return 1;
    return 0;
}

static int option_given(const cli_command *cmd, const char *name)
{
    for (int k = 0; k < cmd->nopts; ++k)
        if (cmd->opts[k].given && strcmp(cmd->opts[k].name, name) == 0) return 1;
    return 0;
}

/* --config FILE: a run parameter file (consph_run_file_load, src/solver/runfile.c). An option
 * given replaces the file's key of the same parameter, and the file's key it clashes with
 * (--steps its tf, --re its nu, --dt its cfl and h_dt, and the other way round). */
typedef consph_run_file run_file;

/* Reads --config FILE into rf; a failure is one line on stderr (exit 2, 1 out of memory). */
static int run_file_load(const cli_command *cmd, const char *path, run_file *rf)
{
    (void)cmd;
    const int st = consph_run_file_load(rf, path);
    if (st == CONSPH_OK) return 0;
    fprintf(stderr, "consph run: option --config: %s\n", consph_last_error());
    return st == CONSPH_ENOMEM ? 1 : CLI_EXIT_USAGE;
}

static int run_file_find(const run_file *rf, const char *name)
{
    return consph_run_file_find(rf, name);
}

/* Whether the parameter `name` is set by an option or by the file (a key not replaced); where
 * into buf ("option --alpha" or "FILE:LINE: key 'alpha'"). */
static int param_given(const cli_command *cmd, const run_file *rf, const char *name, char *buf,
                       size_t size)
{
    const consph_run_param *d = consph_run_param_find(name);
    if (d && d->option && option_given(cmd, d->option)) {
        snprintf(buf, size, "option %s", d->option);
        return 1;
    }
    const int k = run_file_find(rf, name);
    if (k < 0) return 0;
    snprintf(buf, size, "%s:%d: key '%s'", rf->path, rf->key[k].line, rf->key[k].param->study_key);
    return 1;
}

/* Whether an option sets the parameter `name` (consph_run_file_apply's `given`). */
static int option_sets(void *ctx, const char *name)
{
    const consph_run_param *d = consph_run_param_find(name);
    return d && d->option && option_given(ctx, d->option);
}

/* The file's keys into prm, after the problem's defaults and before the options: those an option
 * replaces are checked (a bad value is never ignored) but not applied. */
static int run_file_apply(const cli_command *cmd, run_file *rf, consph_run_params *prm)
{
    if (consph_run_file_apply(rf, prm, option_sets, (void *)cmd) == CONSPH_OK) return 0;
    return cli_error(cmd, "option --config: %s", consph_last_error());
}

/* consph_run_params_unread's `given`: an option, or a key of --config that stays. */
typedef struct given_ctx {
    const cli_command *cmd;
    const run_file *rf;
} given_ctx;

static int given_where(void *ctx, const char *name, char *where, size_t size)
{
    const given_ctx *g = ctx;
    return param_given(g->cmd, g->rf, name, where, size);
}

/* Options (or keys) setting a parameter that this run's scheme or layout does not read would do
 * nothing: refused, naming where they act. */
static int unread_options(const cli_command *cmd, const run_file *rf, const consph_run_params *prm)
{
    given_ctx g = {cmd, rf};
    if (consph_run_params_unread(prm, given_where, &g, "--scheme", "--layout") == CONSPH_OK)
        return 0;
    return cli_error(cmd, "%s", consph_last_error());
}

static int run_heat(const cli_command *cmd, const consph_heat_params *hp, const char *out,
                    long snap_every, int format, int overwrite)
{
    if (consph_heat_params_check(hp) != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return CLI_EXIT_USAGE;
    }
    int rc;
    if (out && (rc = prepare_out(cmd, out, NULL, overwrite)) != 0) return rc;
    consph_heat *h = NULL;
    if (consph_heat_create(&h, hp) != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return 1;
    }
    consph_heat_summary sum;
    int st = consph_heat_run(h, out, snap_every, &sum);
    consph_heat_free(h);
    if (st != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return st == CONSPH_ENUMERIC ? CLI_EXIT_NONFINITE : 1;
    }
    if (format == 1) {
        consph_heat_summary_json(stdout, &sum);
    } else {
        printf("heat %s, walls %s, nx = %d (Δ = %.6g), n = %zu (%zu interior), h/Δ = %g, "
               "ε = %g\n",
               sum.laplacian, sum.walls, sum.nx, sum.delta, sum.n, sum.n_interior, sum.eta,
               sum.eps);
        printf("%ld steps of dt = %.6g (last %.6g, d_min = %.6g) to t = %.6g\n", sum.steps, sum.dt,
               sum.dt_last, sum.d_min, sum.t);
        printf("L2 %.6e  Linf %.6e  EC %.6e  (002 eqs. 44-46)\n", sum.l2, sum.linf, sum.ec);
        printf("%.3f s (set-up %.3f s), %zu correction fallbacks\n", sum.seconds, sum.setup_seconds,
               sum.fallbacks);
    }
    return 0;
}

/* The table's parameters as options of consph run: the text of each, and its help line with
 * what it allows and its default. */
#define RUN_OPTS_MAX 64

typedef struct param_opts {
    const char *text[RUN_OPTS_MAX];
    const consph_run_param *param[RUN_OPTS_MAX];
    char help[RUN_OPTS_MAX][640];
} param_opts;

static int param_options(cli_opt *opts, param_opts *po, const consph_run_params *def)
{
    int n = 0;
    for (int k = 0; k < consph_run_param_count() && n < RUN_OPTS_MAX; ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (!d->option) continue;
        char allowed[512], dflt[64];
        consph_run_param_allowed(d, allowed, sizeof allowed);
        if (consph_run_param_format(def, d->name, dflt, sizeof dflt) != CONSPH_OK) dflt[0] = '\0';
        snprintf(po->help[n], sizeof po->help[n], "%s (%s; default %s)", d->help, allowed, dflt);
        po->text[n] = NULL;
        po->param[n] = d;
        opts[n] =
            (cli_opt){d->option, CLI_STRING, &po->text[n], d->metavar, po->help[n], NULL, 0, 0, 0};
        ++n;
    }
    return n;
}

/* A message of consph_run_params_check begins with the parameter's name: the option in front. */
static int params_refused(const cli_command *cmd)
{
    const char *msg = consph_last_error();
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        const size_t n = strlen(d->name);
        if (d->option && !strncmp(msg, d->name, n) && msg[n] == ' ')
            return cli_error(cmd, "option %s: %s", d->option, msg);
    }
    fprintf(stderr, "consph run: %s\n", msg);
    return CLI_EXIT_USAGE;
}

/* Sets the parameter of every table option given, in table order. */
static int params_given(const cli_command *cmd, const cli_opt *opts, const param_opts *po, int n,
                        consph_run_params *prm)
{
    for (int k = 0; k < n; ++k)
        if (opts[k].given &&
            consph_run_param_set(prm, po->param[k]->name, po->text[k]) != CONSPH_OK)
            return cli_error(cmd, "option %s: %s", opts[k].name, consph_last_error());
    return 0;
}

/* A box as text, "[0, 1]x[0, 1]"; its periodic axes as text, "periodic xy" or "not periodic". */
static void box_text(const consph_box *b, int dim, char *buf, size_t size)
{
    size_t len = 0;
    buf[0] = '\0';
    for (int a = 0; a < dim && len < size; ++a)
        len += (size_t)snprintf(buf + len, size - len, "%s[%.17g, %.17g]", a ? "x" : "", b->lo[a],
                                b->hi[a]);
}

static void periodic_text(const consph_box *b, int dim, char *buf, size_t size)
{
    char axes[4] = "";
    for (int a = 0, k = 0; a < dim; ++a)
        if (b->periodic[a]) axes[k++] = "xyz"[a], axes[k] = '\0';
    snprintf(buf, size, "%s%s", axes[0] ? "periodic " : "not periodic", axes);
}

/* Into *out the field of a particle file named `name` (a snapshot's array) or `other` (a CSV's
 * columns other_0, other_1, ...), with dim components when `vector` (a VTU vector carries 3 in
 * 2D, the third zero) else 1; NULL when it has neither. */
static int file_field(const cli_command *cmd, const char *path, const consph_particles *p,
                      const char *name, const char *other, int vector, const consph_field **out)
{
    const consph_field *a = consph_particles_find(p, name), *b = consph_particles_find(p, other);
    *out = a ? a : b;
    if (a && b)
        return cli_error(cmd, "option --particles: %s has both fields '%s' and '%s': keep one",
                         path, name, other);
    if (!*out) return 0;
    const int want = vector ? p->dim : 1;
    const int pad = vector && p->dim == 2 && (*out)->ncomp == 3;
    if ((*out)->ncomp != want && !pad)
        return cli_error(cmd, "option --particles: %s: field '%s' has %d components, not %d", path,
                         (*out)->name, (*out)->ncomp, want);
    for (size_t i = 0; pad && i < p->n; ++i)
        if ((*out)->data[2 * p->cap + i] != 0.0)
            return cli_error(cmd,
                             "option --particles: %s: field '%s' of particle %zu has z = %.17g, "
                             "but the problem is 2D",
                             path, (*out)->name, i, (*out)->data[2 * p->cap + i]);
    return 0;
}

/* --particles FILE (the readers of consph_read_particles, as `consph approx` reads them): the
 * positions, in the problem's box (a box or periodicity the file states must be the problem's),
 * and the velocity and pressure where the file has them, into `given` as
 * consph_solver_create_from takes them; nx and n from their count. Nothing is written. */
static int read_given(const cli_command *cmd, const char *path, consph_run_params *prm,
                      consph_particles *given)
{
    consph_particle_format fmt;
    if (consph_particle_format_from_path(path, &fmt) != CONSPH_OK)
        return cli_error(cmd, "option --particles: %s", consph_last_error());
    consph_layout_params lp; /* the problem's box and periodicity */
    if (consph_run_layout_params(prm, &lp) != CONSPH_OK)
        return cli_error(cmd, "%s", consph_last_error());
    const int dim = consph_problem_dim(prm->problem);
    consph_read_options ro;
    memset(&ro, 0, sizeof ro);
    ro.dim = dim;
    ro.have_box = ro.have_periodic = 1;
    ro.box = lp.box;
    for (int a = 0; a < dim; ++a) ro.periodic[a] = lp.box.periodic[a];
    consph_particles p;
    consph_read_report rep;
    int st = consph_read_particles(path, &ro, &p, &rep);
    if (st != CONSPH_OK) {
        fprintf(stderr, "consph run: option --particles: %s\n", consph_last_error());
        return st == CONSPH_ENOMEM ? 1 : CLI_EXIT_USAGE;
    }
    char want[160], have[160];
    int bad = 0;
    for (int a = 0; a < dim && rep.file_has_box; ++a)
        bad |= rep.file_box.lo[a] != lp.box.lo[a] || rep.file_box.hi[a] != lp.box.hi[a];
    const char *field = fmt == CONSPH_FORMAT_CSV ? "its '# box' comment" : "its FieldData 'box'";
    if (bad) {
        box_text(&lp.box, dim, want, sizeof want);
        box_text(&rep.file_box, dim, have, sizeof have);
    }
    for (int a = 0; !bad && a < dim && rep.file_has_periodic; ++a)
        if (!rep.file_box.periodic[a] != !lp.box.periodic[a]) {
            bad = 1;
            field =
                fmt == CONSPH_FORMAT_CSV ? "its '# periodic' comment" : "its FieldData 'periodic'";
            periodic_text(&lp.box, dim, want, sizeof want);
            periodic_text(&rep.file_box, dim, have, sizeof have);
        }
    int rc = 0;
    if (bad)
        rc = cli_error(cmd,
                       "option --particles: %s: %s says %s, but problem %s is %s: a run "
                       "takes its problem's box and periodicity",
                       path, field, have, prm->problem, want);
    const consph_field *u = NULL, *pr = NULL;
    if (!rc) rc = file_field(cmd, path, &p, "velocity", "u", 1, &u);
    if (!rc) rc = file_field(cmd, path, &p, "pressure", "p", 0, &pr);
    if (!rc && consph_run_params_particles(prm, p.n) != CONSPH_OK)
        rc = cli_error(cmd, "option --particles: %s: %s", path, consph_last_error());
    if (!rc && consph_particles_init(given, dim, p.n, &p.box) != CONSPH_OK) rc = 1;
    for (int a = 0; !rc && a < dim; ++a) memcpy(given->x[a], p.x[a], p.n * sizeof(double));
    double *gu = !rc && u ? consph_particles_field(given, "u", dim) : NULL;
    double *gp = !rc && pr ? consph_particles_field(given, "p", 1) : NULL;
    if (!rc && ((u && !gu) || (pr && !gp))) rc = 1;
    for (int a = 0; gu && !rc && a < dim; ++a)
        memcpy(gu + (size_t)a * given->cap, u->data + (size_t)a * p.cap, p.n * sizeof(double));
    if (gp && !rc) memcpy(gp, pr->data, p.n * sizeof(double));
    if (rc == 1) fprintf(stderr, "consph run: %s\n", consph_last_error());
    consph_particles_free(&p);
    return rc;
}

int cmd_run_started;

int cmd_run(int argc, char **argv)
{
    consph_run_params prm;
    consph_run_params_default(&prm);
    const char *out = NULL, *restart = NULL, *particles = NULL, *config = NULL;
    static run_file rf;
    consph_particles given;
    memset(&given, 0, sizeof given);
    long snap_every = 0, ckpt_every = 0, threads = 0;
    int format = 0, heat_lap = 1, heat_walls = 0, device = CONSPH_DEVICE_CPU;
    int overwrite = 0;
    cli_cache cache = {NULL, 0};
    double heat_eta = 2.0, heat_eps = 0.0;
    static param_opts po;
    cli_opt opts[RUN_OPTS_MAX + 24];
    const int nparam = param_options(opts, &po, &prm);
    const cli_opt others[] = {
        {"--out", CLI_STRING, &out, "DIR", "write snapshots, log, summary, checkpoints here", NULL,
         0, 0, 0},
        {"--snapshot-every", CLI_INT, &snap_every, "K",
         "a snapshot every K steps (0: first and "
         "last)",
         NULL, 0, 1e12, 0},
        {"--checkpoint-every", CLI_INT, &ckpt_every, "K", "a checkpoint every K steps", NULL, 0,
         1e12, 0},
        {"--overwrite", CLI_FLAG, &overwrite, NULL,
         "remove the files of an earlier run in --out first (only those)", NULL, 0, 0, 0},
        {"--restart", CLI_STRING, &restart, "FILE",
         "continue from a checkpoint (with --tf or --steps: to another end)", NULL, 0, 0, 0},
        {"--particles", CLI_STRING, &particles, "FILE",
         "start from these particles (CSV or VTU: positions, optional velocity and pressure) "
         "instead of --layout; nx from their count",
         NULL, 0, 0, 0},
        {"--config", CLI_STRING, &config, "FILE",
         "run parameters as key = value lines (the run keys of study files); options given "
         "replace its keys",
         NULL, 0, 0, 0},
        {"--format", CLI_CHOICE, &format, "F", "result on stdout", "table,json", 0, 0, 0},
        {"--threads", CLI_INT, &threads, "T", "threads (0: OpenMP's default)", NULL, 0, 4096, 0},
        {"--device", CLI_CHOICE, &device, "D", "where the steps run (gpu: docs/gpu.md)", "cpu,gpu",
         0, 0, 0},
        {"--laplacian", CLI_CHOICE, &heat_lap, "L", "heat: the Laplacian (002 S3 or S4)", "s3,s4",
         0, 0, 0},
        {"--eta", CLI_DOUBLE, &heat_eta, "H/Δ", "heat: h/Δ", NULL, 1, 10, 0},
        {"--eps", CLI_DOUBLE, &heat_eps, "E", "heat: perturbation ε of the interior (002 §6.2)",
         NULL, 0, 1, 0},
        {"--walls", CLI_CHOICE, &heat_walls, "W", "heat: boundary data", "sin,linear", 0, 0, 0},
        CLI_CACHE_OPTS(cache),
    };
    const int nothers = (int)(sizeof others / sizeof others[0]);
    for (int k = 0; k < nothers; ++k) opts[nparam + k] = others[k];
    const char *positional[1] = {NULL};
    char usage[512];
    snprintf(usage, sizeof usage,
             "consph run PROBLEM --scheme S --nx N [options]   (PROBLEM: %s)\n"
             "       consph run PROBLEM --particles FILE [options]   consph run --config FILE "
             "[options]\n"
             "       consph run --restart CKPT [--tf T | --steps K] [output options]\n"
             "       consph run heat --laplacian s3|s4 --nx N --eta H/Δ [options]",
             consph_problem_names());
    cli_command cmd = {"run", "run a simulation: weakly-compressible SPH, or 002's heat problem",
                       usage, run_details,
                       opts,  nparam + nothers,
                       1,     positional};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    if ((rc = cli_cache_apply(&cmd, &cache))) return rc;
    if (config && !restart && (rc = run_file_load(&cmd, config, &rf)) != 0) return rc;
    const run_file *cf = config && !restart ? &rf : NULL;
    const int file_problem = run_file_find(cf, "problem");
    const char *problem = positional[0]       ? positional[0]
                          : file_problem >= 0 ? rf.key[file_problem].value
                                              : NULL;
    if (!problem && !restart)
        return cli_error(&cmd, "a problem is required (allowed: %s, heat)%s",
                         consph_problem_names(), config ? ", or a key 'problem' in --config" : "");
    /* Before the packing, the restart or the run, not at their first write. */
    if (out && (rc = cli_check_out_dir(&cmd, "--out", out)) != 0) return rc;
    if (threads > 0) consph_set_num_threads((int)threads);
    const int heat = positional[0] && strcmp(positional[0], "heat") == 0;
    /* Under K > 1 MPI ranks the WCSPH solver is decomposed (below, consph_par_solver_decompose);
     * 002's conduction solver is not, and K copies of it would write the same files. */
    if (heat && consph_par_size() > 1)
        return cli_error(&cmd,
                         "problem heat is not decomposed over MPI ranks (launched on %d): run it "
                         "without mpirun (or with -np 1)",
                         consph_par_size());
    if (device == CONSPH_DEVICE_GPU && consph_par_size() > 1)
        return cli_error(&cmd,
                         "option --device gpu runs on one process: launched on %d MPI ranks, run "
                         "it without mpirun (or with -np 1)",
                         consph_par_size());
    for (int k = 0; k < cmd.nopts; ++k) {
        if (!opts[k].given) continue;
        const int heat_only = strncmp(opts[k].help, "heat: ", 6) == 0;
        if (heat_only && !heat)
            return cli_error(&cmd, "option %s is for the problem heat only", opts[k].name);
        if (heat && !heat_only && !heat_option(opts[k].name))
            return cli_error(&cmd,
                             "option %s is not an option of the problem heat (allowed: "
                             "--laplacian, --nx, --eta, --eps, --seed, --tf, --steps, --walls, "
                             "--out, --snapshot-every, --overwrite, --format, --threads)",
                             opts[k].name);
    }
    /* options that would do nothing in this combination are refused, not ignored */
    if (option_given(&cmd, "--steps") && option_given(&cmd, "--tf"))
        return cli_error(&cmd, "options --steps and --tf both set the end of the run: give one");
    static const char *const need_out[] = {"--snapshot-every", "--checkpoint-every", "--overwrite"};
    for (size_t k = 0; k < sizeof need_out / sizeof need_out[0]; ++k)
        if (!out && option_given(&cmd, need_out[k]))
            return cli_error(&cmd, "option %s acts on the files of --out DIR: give --out",
                             need_out[k]);
    if (restart && overwrite)
        return cli_error(&cmd, "option --overwrite is for a new run: --restart continues its own "
                               "run's files (give another --out to continue elsewhere)");
    if (heat && option_given(&cmd, "--seed") && !(heat_eps > 0.0))
        return cli_error(&cmd, "option --seed does nothing for heat without --eps (> 0): the "
                               "seed draws only the perturbation of the interior");
    if (heat) {
        consph_heat_params hp;
        consph_heat_params_default(&hp);
        hp.laplacian = (consph_heat_lap)heat_lap;
        hp.walls = (consph_heat_walls)heat_walls;
        /* the options heat shares read as the run's (their bounds), but --nx, whose bounds are
         * heat's own (consph_heat_params_check) */
        consph_run_params shared = prm;
        for (int k = 0; k < nparam; ++k) {
            if (!opts[k].given) continue;
            if (!strcmp(opts[k].name, "--nx")) {
                char *end;
                errno = 0;
                const long v = strtol(po.text[k], &end, 10);
                if (end == po.text[k] || *end || errno || v < 4 || v > 1000000000L)
                    return cli_error(&cmd, "option --nx: '%.40s' is not an integer in [4, 1e9]",
                                     po.text[k]);
                hp.nx = (int)v;
            } else if (consph_run_param_set(&shared, po.param[k]->name, po.text[k]) != CONSPH_OK) {
                return cli_error(&cmd, "option %s: %s", opts[k].name, consph_last_error());
            }
        }
        hp.eta = heat_eta;
        hp.eps = heat_eps;
        hp.seed = shared.seed;
        if (option_given(&cmd, "--tf")) hp.tf = shared.tf;
        hp.steps = shared.steps;
        return run_heat(&cmd, &hp, out, snap_every, format, overwrite);
    }

    consph_solver *s = NULL;
    int st;
    if (restart) {
        static const char *const with_restart[] = {
            "--restart",          "--out", "--format", "--threads", "--snapshot-every",
            "--checkpoint-every", "--tf",  "--steps",  "--device"};
        for (int k = 0; k < cmd.nopts; ++k) {
            size_t w = 0;
            while (w < sizeof with_restart / sizeof with_restart[0] &&
                   strcmp(opts[k].name, with_restart[w]))
                ++w;
            if (opts[k].given && w == sizeof with_restart / sizeof with_restart[0])
                return cli_error(
                    &cmd,
                    "option %s cannot change a restarted run (allowed with --restart: "
                    "--out, --format, --threads, --snapshot-every, --checkpoint-every, --device, "
                    "and a new end: --tf or --steps)",
                    opts[k].name);
        }
        if (positional[0]) return cli_error(&cmd, "give no problem with --restart");
        /* the new end, read with the table's bounds */
        consph_run_params end = prm;
        if ((rc = params_given(&cmd, opts, &po, nparam, &end)) != 0) return rc;
        st = consph_par_run_restart(&s, restart); /* on K ranks each reads its part */
        if (st != CONSPH_OK) {
            fprintf(stderr, "consph run: option --restart: %s\n", consph_last_error());
            return CLI_EXIT_USAGE;
        }
        const int new_tf = option_given(&cmd, "--tf"), new_steps = option_given(&cmd, "--steps");
        if ((new_tf || new_steps) && consph_solver_extend(s, new_tf ? end.tf : 0.0,
                                                          new_steps ? end.steps : 0) != CONSPH_OK) {
            rc = cli_error(&cmd, "option %s: checkpoint '%s': %s", new_tf ? "--tf" : "--steps",
                           restart, consph_last_error());
            consph_solver_free(s);
            return rc;
        }
        if (out && (rc = prepare_out(&cmd, out, consph_solver_run_id(s), 0)) != 0) {
            consph_solver_free(s);
            return rc;
        }
    } else {
        if (option_given(&cmd, "--re") && option_given(&cmd, "--nu"))
            return cli_error(&cmd, "options --re and --nu both set the viscosity: give one");
        if (consph_run_params_problem(&prm, problem) != CONSPH_OK) {
            if (positional[0])
                return cli_error(&cmd, "problem '%.40s' is unknown (allowed: %s, heat)", problem,
                                 consph_problem_names());
            return cli_error(&cmd,
                             "option --config: %s:%d: key 'problem': problem '%.40s' is unknown "
                             "(allowed: %s)",
                             rf.path, rf.key[file_problem].line, problem, consph_problem_names());
        }
        /* the problem's defaults (consph_run_params_problem) stay unless the file's key or an
         * option is given, in that order */
        if (cf && (rc = run_file_apply(&cmd, &rf, &prm)) != 0) return rc;
        if ((rc = params_given(&cmd, opts, &po, nparam, &prm)) != 0) return rc;
        char where[320];
        if (particles) {
            static const char *const layout_only[] = {"nx", "layout", "seed"};
            for (size_t k = 0; k < sizeof layout_only / sizeof layout_only[0]; ++k)
                if (param_given(&cmd, cf, layout_only[k], where, sizeof where))
                    return cli_error(&cmd,
                                     "%s: not with --particles (the file's particles and their "
                                     "count replace the layout)",
                                     where);
        }
        if (param_given(&cmd, cf, "re", where, sizeof where)) prm.nu = -1.0; /* ν from Re */
        if (param_given(&cmd, cf, "steps", where, sizeof where)) prm.tf = 0.0;
        if (prm.dt > 0.0 && (param_given(&cmd, cf, "cfl", where, sizeof where) ||
                             param_given(&cmd, cf, "h_dt", where, sizeof where)))
            return cli_error(&cmd, "%s sets the time-step rule, which %s %g replaces: give one",
                             where, option_given(&cmd, "--dt") ? "--dt" : "dt", prm.dt);
        if (param_given(&cmd, cf, "error_times", where, sizeof where) &&
            prm.error != CONSPH_ERROR_AUTHORS)
            return cli_error(&cmd,
                             "%s counts the output times of --error authors: give --error "
                             "authors too",
                             where);
        if (consph_run_params_check(&prm) != CONSPH_OK) return params_refused(&cmd);
        if ((rc = unread_options(&cmd, cf, &prm)) != 0) return rc;
        if (particles) {
            /* under K ranks rank 0 alone reads and checks the file (its messages once) and
             * hands each rank its share */
            const int ranks = consph_par_size() > 1;
            rc = !ranks || consph_par_rank() == 0 ? read_given(&cmd, particles, &prm, &given) : 0;
            if (ranks) rc = consph_par_bcast_int(rc);
            if (ranks && !rc && consph_par_given_share(&prm, &given) != CONSPH_OK) {
                fprintf(stderr, "consph run: option --particles: %s\n", consph_last_error());
                rc = 1;
            }
            if (!rc && consph_run_params_check(&prm) != CONSPH_OK)
                rc = cli_error(&cmd, "option --particles: %s: %s", particles, consph_last_error());
        }
        if (!rc && out) rc = prepare_out(&cmd, out, NULL, overwrite);
        if (rc) {
            consph_particles_free(&given);
            return rc;
        }
    }
    /* the GPU's refusals before the set-up's work (bad input: exit 2) */
    if (device == CONSPH_DEVICE_GPU) {
        if (consph_gpu_check(s ? consph_solver_params(s) : &prm) != CONSPH_OK)
            rc = cli_error(&cmd, "%s", consph_last_error());
        if (rc) {
            consph_solver_free(s);
            consph_particles_free(&given);
            return rc;
        }
    }
    /* Under K > 1 ranks the solver is cut before its neighbour list and initial rates, so no
     * rank holds the whole solver; a failure once the ranks agreed is the run's (exit 2 when
     * the decomposition refuses the launch). */
    int par_joined = 0;
    if (!s && consph_par_size() > 1) {
        st = consph_par_solver_create(&s, &prm, particles ? &given : NULL, &par_joined);
        cmd_run_started = par_joined;
        if (st != CONSPH_OK) {
            fprintf(stderr, "consph run: %s\n", consph_last_error());
            consph_particles_free(&given);
            return st == CONSPH_EINVAL && par_joined ? CLI_EXIT_USAGE : 1;
        }
    }
    if (!s && (st = particles ? consph_solver_create_from(&s, &prm, &given)
                              : consph_solver_create(&s, &prm)) != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        consph_particles_free(&given);
        /* bad input the set-up finds (CONSPH_PAIR_CACHE_MB, a particle file's values) */
        return st == CONSPH_EINVAL ? CLI_EXIT_USAGE : 1;
    }
    consph_particles_free(&given);
    if (device == CONSPH_DEVICE_GPU &&
        consph_solver_set_device(s, CONSPH_DEVICE_GPU) != CONSPH_OK) {
        fprintf(stderr, "consph run: --device gpu: %s\n", consph_last_error());
        consph_solver_free(s);
        return 1;
    }
    if (consph_par_size() > 1) {
        /* every rank made the same solver; from the decomposition on they run it together. The
         * agreement first: a rank that stopped earlier joins it from main (apps/consph.c). */
        st = CONSPH_OK;
        if (!par_joined) {
            cmd_run_started = 1;
            st = consph_par_agree(CONSPH_OK);
            if (st == CONSPH_OK) st = consph_par_solver_decompose(s);
        }
        if (st != CONSPH_OK) {
            fprintf(stderr, "consph run: %s\n", consph_last_error());
            consph_solver_free(s);
            return st == CONSPH_EINVAL ? CLI_EXIT_USAGE : 1;
        }
    }
    char warn[256];
    if (consph_solver_dt_warning(s, warn, sizeof warn))
        fprintf(stderr,
                "consph run: warning: %s; the run may stop where it leaves the model's "
                "validity\n",
                warn);
    consph_run_output ro = {out, snap_every, ckpt_every, 1, 1};
    consph_run_summary sum;
    int sig = 0;
    st = consph_run(s, &ro, &sum, &sig);
    const int against_wc = sum.exact == CONSPH_EXACT_WC;
    if (consph_par_size() > 1 && st == CONSPH_OK && !sig) {
        /* every rank follows rank 0's status, so every rank takes part in these sums. On stderr:
         * stdout and summary.json stay the serial run's (tests/cli_mpi.sh) */
        double bytes, secs;
        consph_par_solver_comm(s, &bytes, &secs);
        const long all_bytes = consph_par_sum_long((long)bytes);
        const long all_us = consph_par_sum_long((long)(secs * 1e6));
        const double mean_secs = 1e-6 * (double)all_us / consph_par_size();
        fprintf(stderr,
                "consph run: MPI %d ranks: %ld bytes sent (%.1f per particle-step), %.3f s in MPI "
                "calls per rank (mean; %.1f%% of the steps' %.3f s)\n",
                consph_par_size(), all_bytes,
                sum.steps ? (double)all_bytes / ((double)sum.steps * (double)sum.n) : 0.0,
                mean_secs, sum.seconds > 0.0 ? 100.0 * mean_secs / sum.seconds : 0.0, sum.seconds);
    }
    consph_solver_free(s);
    if (st == CONSPH_ENUMERIC) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return CLI_EXIT_NONFINITE;
    }
    if (st != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return 1;
    }
    if (sig) {
        fprintf(stderr, "consph run: stopped by signal %d at step %ld (t = %.6g)%s%s%s\n", sig,
                sum.steps, sum.t, out ? "; checkpoint " : "", out ? out : "",
                out ? "/checkpoint.ckpt" : "");
        return 128 + sig;
    }
    if (format == 1) {
        consph_run_summary_json(stdout, &sum);
    } else {
        printf("%s %s, %s, n = %zu, %ld steps of dt = %.6g to t = %.6g, c_o = %g\n", sum.problem,
               sum.scheme, sum.integrator, sum.n, sum.steps, sum.dt, sum.t, sum.c0);
        char e[4][32];
        const double ev[4] = {sum.l1_u, sum.l1_p, sum.linf_u, sum.linf_p};
        for (int k = 0; k < 4; ++k) error_text(e[k], sizeof e[k], ev[k]);
        if (sum.error == CONSPH_ERROR_AUTHORS) {
            char a[2][32];
            error_text(a[0], sizeof a[0], sum.l1n_u);
            error_text(a[1], sizeof a[1], sum.l1n_p);
            printf("L1(u) %s  L1(p) %s  (001's authors: mean over %d output times%s)\n", a[0], a[1],
                   sum.error_samples, against_wc ? ", against wc" : "");
        }
        printf("L1(u) %s  L1(p) %s  (001 eq. 26%s)   Linf(u) %s  Linf(p) %s\n", e[0], e[1],
               against_wc ? ", against wc" : "", e[2], e[3]);
        if (sum.exact == CONSPH_EXACT_BOTH) {
            char w[4][32];
            const double wv[4] = {sum.wc_l1n_u, sum.wc_l1n_p, sum.wc_l1_u, sum.wc_l1_p};
            for (int k = 0; k < 4; ++k) error_text(w[k], sizeof w[k], wv[k]);
            if (sum.error == CONSPH_ERROR_AUTHORS)
                printf("L1(u) %s  L1(p) %s  (001's authors, against wc)\n", w[0], w[1]);
            printf("L1(u) %s  L1(p) %s  (001 eq. 26, against wc)\n", w[2], w[3]);
        }
        if (sum.dim == 3)
            printf("momentum (%.3e, %.3e, %.3e)  ", sum.momentum[0], sum.momentum[1],
                   sum.momentum[2]);
        else
            printf("momentum (%.3e, %.3e)  ", sum.momentum[0], sum.momentum[1]);
        printf("angular %.3e  F_T/F_max %.3e  max|div u| %.3e\n", sum.angular_momentum, sum.ft_fmax,
               sum.max_divu);
        printf("%.3f s, %.3e s per particle-step, %d passes per stage (minimum %d)\n", sum.seconds,
               sum.steps ? sum.seconds / ((double)sum.steps * (double)sum.n) : 0.0,
               sum.passes_per_stage, sum.passes_min);
    }
    return 0;
}
