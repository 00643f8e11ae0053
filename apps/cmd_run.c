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
    "again). A DIR holding another run's files is refused: a new run needs --overwrite (which\n"
    "removes those files, nothing else), a restart its own run's DIR (DIR/run.id) or a new one.\n"
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

/* Options setting a parameter that this run's scheme or layout does not read would do nothing:
 * refused, naming where they act (the table's `reads`: consph_scheme_reads;
 * consph_layout_uses_seed). --eos default is the scheme's own EOS, so it is no setting. */
static int unread_options(const cli_command *cmd, const consph_run_params *prm)
{
    char list[512];
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (!d->reads || !d->option || !option_given(cmd, d->option) ||
            (d->reads == CONSPH_PARAM_EOS && !strcmp(d->name, "eos") &&
             prm->eos == CONSPH_EOS_DEFAULT) ||
            consph_scheme_reads(prm->scheme, d->reads))
            continue;
        return cli_error(cmd, "option %s does nothing for --scheme %s (it acts on: %s)", d->option,
                         prm->scheme, consph_scheme_readers(d->reads, list, sizeof list));
    }
    const int layout = consph_run_params_layout(prm);
    if (!option_given(cmd, "--seed") || layout < 0 ||
        consph_layout_uses_seed((consph_layout_kind)layout))
        return 0;
    return cli_error(cmd,
                     "option --seed does nothing for --layout %s (%s), which draws no random "
                     "numbers (it acts on: %s)",
                     consph_layout_name((consph_layout_kind)layout),
                     option_given(cmd, "--layout") ? "given" : "the problem's or scheme's default",
                     consph_layout_seeded_names(list, sizeof list));
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

int cmd_run(int argc, char **argv)
{
    consph_run_params prm;
    consph_run_params_default(&prm);
    const char *out = NULL, *restart = NULL;
    long snap_every = 0, ckpt_every = 0, threads = 0;
    int format = 0, heat_lap = 1, heat_walls = 0;
    int overwrite = 0;
    cli_cache cache = {NULL, 0};
    double heat_eta = 2.0, heat_eps = 0.0;
    static param_opts po;
    cli_opt opts[RUN_OPTS_MAX + 16];
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
        {"--restart", CLI_STRING, &restart, "FILE", "continue from a checkpoint", NULL, 0, 0, 0},
        {"--format", CLI_CHOICE, &format, "F", "result on stdout", "table,json", 0, 0, 0},
        {"--threads", CLI_INT, &threads, "T", "threads (0: OpenMP's default)", NULL, 0, 4096, 0},
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
             "       consph run heat --laplacian s3|s4 --nx N --eta H/Δ [options]",
             consph_problem_names());
    cli_command cmd = {"run", "run a simulation: weakly-compressible SPH, or 002's heat problem",
                       usage, run_details,
                       opts,  nparam + nothers,
                       1,     positional};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    /* Under K > 1 MPI ranks (mpirun -np K): the entry point of the solver's domain decomposition
     * goes here. Until it exists, K copies of one serial run would write the same files. */
    if (consph_par_size() > 1)
        return cli_error(&cmd,
                         "launched on %d MPI ranks: consph run does not decompose a run over "
                         "ranks yet; run it without mpirun (or with -np 1)",
                         consph_par_size());
    if ((rc = cli_cache_apply(&cmd, &cache))) return rc;
    if (!positional[0] && !restart)
        return cli_error(&cmd, "a problem is required (allowed: %s, heat)", consph_problem_names());
    /* Before the packing, the restart or the run, not at their first write. */
    if (out && (rc = cli_check_out_dir(&cmd, "--out", out)) != 0) return rc;
    if (threads > 0) consph_set_num_threads((int)threads);
    const int heat = positional[0] && strcmp(positional[0], "heat") == 0;
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
        for (int k = 0; k < cmd.nopts; ++k)
            if (opts[k].given && strcmp(opts[k].name, "--restart") &&
                strcmp(opts[k].name, "--out") && strcmp(opts[k].name, "--format") &&
                strcmp(opts[k].name, "--threads") && strcmp(opts[k].name, "--snapshot-every") &&
                strcmp(opts[k].name, "--checkpoint-every"))
                return cli_error(
                    &cmd,
                    "option %s cannot change a restarted run (allowed with --restart: "
                    "--out, --format, --threads, --snapshot-every, --checkpoint-every)",
                    opts[k].name);
        if (positional[0]) return cli_error(&cmd, "give no problem with --restart");
        st = consph_run_restart(&s, restart);
        if (st != CONSPH_OK) {
            fprintf(stderr, "consph run: option --restart: %s\n", consph_last_error());
            return CLI_EXIT_USAGE;
        }
        if (out && (rc = prepare_out(&cmd, out, consph_solver_run_id(s), 0)) != 0) {
            consph_solver_free(s);
            return rc;
        }
    } else {
        if (option_given(&cmd, "--re") && option_given(&cmd, "--nu"))
            return cli_error(&cmd, "options --re and --nu both set the viscosity: give one");
        if (consph_run_params_problem(&prm, positional[0]) != CONSPH_OK)
            return cli_error(&cmd, "problem '%.40s' is unknown (allowed: %s, heat)", positional[0],
                             consph_problem_names());
        /* the problem's defaults (consph_run_params_problem) stay unless an option is given */
        if ((rc = params_given(&cmd, opts, &po, nparam, &prm)) != 0) return rc;
        if (option_given(&cmd, "--re")) prm.nu = -1.0; /* ν from the Re given */
        if (option_given(&cmd, "--steps")) prm.tf = 0.0;
        if (prm.dt > 0.0 && (option_given(&cmd, "--cfl") || option_given(&cmd, "--h-dt")))
            return cli_error(&cmd,
                             "option %s sets the time-step rule, which --dt %g replaces: "
                             "give one",
                             option_given(&cmd, "--cfl") ? "--cfl" : "--h-dt", prm.dt);
        if (option_given(&cmd, "--error-times") && prm.error != CONSPH_ERROR_AUTHORS)
            return cli_error(&cmd, "option --error-times counts the output times of --error "
                                   "authors: give --error authors too");
        if (consph_run_params_check(&prm) != CONSPH_OK) return params_refused(&cmd);
        if ((rc = unread_options(&cmd, &prm)) != 0) return rc;
        if (out && (rc = prepare_out(&cmd, out, NULL, overwrite)) != 0) return rc;
    }
    if (!s && (st = consph_solver_create(&s, &prm)) != CONSPH_OK) {
        fprintf(stderr, "consph run: %s\n", consph_last_error());
        return 1;
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
