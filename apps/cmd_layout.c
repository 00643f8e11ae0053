/* consph layout: generate a particle arrangement (or read one with --in), print its statistics,
 * write it as .vtu/.csv. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "commands.h"
#include "consph/io.h"
#include "consph/kernels.h"
#include "consph/layout.h"

static const char layout_details[] =
    "kinds (unit box [0,1)^D, Δs = 1/N, N^D particles):\n"
    "  lattice       cell-centred lattice x = (i + 1/2) Δs (001's UP arrangement)\n"
    "  random        lattice + ε κ Δs per coordinate, κ uniform in [-0.25, 0.25] (002 §6.2);\n"
    "                reproducible for a given --seed\n"
    "  quasi-random  Halton points (bases 2, 3, 5; sequence indices 1..N^D, index 0 skipped)\n"
    "                filling the box (003 §6.2); spacing (V/N)^(1/D)\n"
    "  packed        001's PP arrangement as [51] (Negi & Ramachandran 2021) and its authors'\n"
    "                code (PySPH particle_packing.py) make it: the lattice perturbed by up to\n"
    "                --perturb Δs per coordinate, relaxed by damped motion under a background\n"
    "                pressure and a short-range repulsion with --kernel and --hdx (quintic,\n"
    "                1.2), explicit Euler steps, until the particles stop moving: every 50\n"
    "                steps, from the 11th test on, 100 max|u| Δt / h <= --move-tol; or\n"
    "                --max-iter steps (default 40000). Needs a periodic box.\n"
    "                --walls L packs instead inside L frozen lattice layers around the box\n"
    "                (PySPH's frozen container) and returns the particles in the periodic\n"
    "                box, wall rows meeting at its edges: how the authors' files were made.\n"
    "  packed-polished  consph's two-stage relaxation: that packing (with the quintic at\n"
    "                h = 1.2Δs, symplectic steps) until it stalls, then a damped descent of\n"
    "                sum_i (rho_i/rho0 - 1)^2 with --kernel and --hdx, until\n"
    "                max|rho/rho0 - 1| < --tol or --max-iter steps (default 5000).\n"
    "                For both, perturbations below about 0.35 relax back to the lattice.\n"
    "\n"
    "Every kind adds the per-particle field 'volume' = box volume / particle count. The printed\n"
    "statistics use the summation density rho_i = sum_j m W_ij with m = Δs^D (rho0 = 1) and the\n"
    "kernel --kernel with h = --hdx Δs, the minimum pair distance, the nearest-neighbour\n"
    "distances and the distance of each particle from the nearest lattice node (in units of Δs).\n"
    "\n"
    "output: .vtu (VTK XML unstructured grid) or .csv, chosen by the extension of --out. A .vtu\n"
    "holds its arrays as --vtu-encoding says: zlib (default; binary appended data in\n"
    "zlib-compressed blocks, as ParaView saves), binary (the same uncompressed) or ascii (text).\n"
    "The CSV starts with '#' comment lines (dim, n, spacing, box, periodic), then the header row\n"
    "x,y[,z],volume and one row per particle.\n"
    "\n"
    "--in FILE reads particles instead of generating them (CSV with a header row x,y[,z] and\n"
    "optional volume, m, rho columns, or .vtu: ascii, binary, appended, zlib), prints the same\n"
    "statistics and, with --out, writes them in the other format: a converter. The box and\n"
    "periodicity are the file's (consph's '#' header or VTU field data) unless --box and\n"
    "--periodic are given; the spacing is the file's, else (box volume / N)^(1/D), and must\n"
    "lie in [1e-50, 1e50] (kernels divide by h^(D+2)). A lone particle in a box that is not\n"
    "periodic has no neighbour: its spacing statistics print as n/a.\n"
    "\n"
    "The packed kinds are kept in a cache of layouts (--cache DIR, default\n"
    "$XDG_CACHE_HOME/consph or ~/.cache/consph; --no-cache to bypass it): the same parameters\n"
    "read the file instead of packing again. README.md says what the key holds and how to\n"
    "clear it.\n"
    "\n"
    "exit status: 0 success, 1 failure while running, 2 bad usage (nothing is written)";

static int opt_given(const cli_opt *opts, int nopts, const char *name)
{
    for (int k = 0; k < nopts; ++k)
        if (strcmp(opts[k].name, name) == 0) return opts[k].given;
    return 0;
}

/* Statistics of any particle set, as printed for generated layouts. */
static int print_stats(const consph_particles *p, const char *kernel, double hdx)
{
    consph_layout_stats st;
    consph_layout_nn_stats nst;
    int rc = consph_layout_stats_compute(p, kernel, hdx, &st);
    if (!rc) rc = consph_layout_nn_stats_compute(p, &nst);
    if (rc) {
        fprintf(stderr, "consph layout: %s\n", consph_last_error());
        return rc;
    }
    /* One particle in a box that is not periodic has no neighbour, so no spacing: n/a, not inf
     * and nan. The file is valid and its density and lattice distance are defined, so this is
     * no error (periodic, its images are its neighbours). */
    const int alone = !isfinite(st.min_spacing) || !isfinite(nst.nn_min);
    if (alone)
        printf("min spacing n/a (%zu particle, no pair)\n", p->n);
    else
        printf("min spacing %.6g (%.4f Δs)\n", st.min_spacing, st.min_spacing / p->spacing);
    printf("density (%s, h/Δs %g): max|rho/rho0-1| %.3e, mean rho %.9f\n", kernel, hdx,
           st.rho_spread, st.rho_mean);
    if (alone)
        printf("nearest-neighbour distance / Δs: n/a (no neighbour)\n");
    else
        printf("nearest-neighbour distance / Δs: min %.4f mean %.4f max %.4f std %.4f\n",
               nst.nn_min, nst.nn_mean, nst.nn_max, nst.nn_std);
    printf("distance to the nearest lattice node / Δs: mean %.4f max %.4f\n", nst.disp_mean,
           nst.disp_max);
    return CONSPH_OK;
}

/* consph layout --in FILE [--out FILE2]: read, summarise, convert. */
static int layout_from_file(const cli_command *cmd, const char *in, const char *out, long dim,
                            const char *box_text, int periodic_given, int periodic,
                            const char *kernel, double hdx, consph_vtu_encoding enc)
{
    consph_read_options ro;
    memset(&ro, 0, sizeof ro);
    ro.dim = (int)dim;
    if (box_text) {
        if (cli_parse_box(box_text, &ro.box)) return cli_bad_box(cmd, box_text);
        ro.have_box = 1;
    }
    if (periodic_given) {
        ro.have_periodic = 1;
        for (int a = 0; a < CONSPH_MAX_DIM; ++a) ro.periodic[a] = periodic;
    }
    consph_particle_format fmt;
    if (out && consph_particle_format_from_path(out, &fmt) != CONSPH_OK)
        return cli_error(cmd, "option --out: %s", consph_last_error());
    consph_particles p;
    consph_read_report rep;
    if (consph_read_particles(in, &ro, &p, &rep) != CONSPH_OK) {
        fprintf(stderr, "consph layout: %s\n", consph_last_error());
        return CLI_EXIT_USAGE;
    }
    static const char axis[] = "xyz";
    printf("read %s (%s%s%s): %zu particles, dim %d, spacing %.6g%s, box", in,
           rep.format == CONSPH_FORMAT_CSV ? "csv" : "vtu", rep.encoding[0] ? " " : "",
           rep.encoding, p.n, p.dim, p.spacing, rep.spacing_from_file ? "" : " ((V/N)^(1/D))");
    for (int a = 0; a < p.dim; ++a) printf("%s[%g, %g]", a ? "x" : " ", p.box.lo[a], p.box.hi[a]);
    printf("%s, periodic ", rep.box_from_file ? "" : " (--box)");
    int any = 0;
    for (int a = 0; a < p.dim; ++a)
        if (p.box.periodic[a]) any = 1, putchar(axis[a]);
    printf("%s, volumes %s", any ? "" : "none", consph_volume_origin_name(rep.volumes));
    if (rep.wrapped) printf(", %zu wrapped into the periodic box", rep.wrapped);
    printf("\n");
    int rc = print_stats(&p, kernel, hdx);
    if (rc == CONSPH_OK && out) {
        rc = consph_write_particles_enc(out, &p, enc);
        if (rc)
            fprintf(stderr, "consph layout: %s\n", consph_last_error());
        else
            printf("wrote %s\n", out);
    }
    consph_particles_free(&p);
    return rc ? 1 : 0;
}

static void print_report(const consph_packing_report *r, const consph_layout_params *lp)
{
    const int converged = r->converged, polished = lp->kind == CONSPH_LAYOUT_PACKED_POLISHED;
    printf("packing: %d iterations in %.3f s%s, max|rho/rho0-1| %.3e -> %.3e", r->iterations,
           r->seconds, r->from_cache ? " (read from the layout cache)" : "", r->rho_spread_initial,
           r->rho_spread_final);
    if (polished)
        printf(" (tol %.1e, %s)\n", lp->packing.tol,
               converged ? "converged" : "NOT converged: --max-iter reached");
    else
        printf(" (100 max|u| dt/h %.3g, move-tol %.1e, %s)\n", r->move_final, lp->packing.move_tol,
               converged ? "converged" : "NOT converged: --max-iter reached");
    if (r->iterations == 0)
        printf("  no packing step (--max-iter 0): the initial arrangement, unrelaxed\n");
    else if (!polished)
        printf("  the single stage of [51]\n");
    else if (r->polish_start >= 0)
        printf("  glass stage: iterations 0..%d; density polishing from iteration %d\n",
               r->polish_start, r->polish_start);
    else
        printf("  glass stage only (%s before density polishing)\n",
               converged ? "the tolerance was met" : "--max-iter was reached");
    if (r->nhistory > 0) {
        printf("  %9s  %s\n", "iteration", "max|rho/rho0-1|");
        for (int k = 0; k < r->nhistory; ++k)
            printf("  %9d  %.3e\n", r->history_iter[k], r->history_spread[k]);
    }
}

int cmd_layout(int argc, char **argv)
{
    int kind_index = -1, periodic_index = 0, encoding_index = CONSPH_VTU_DEFAULT;
    long dim = 0, nx = 0, seed = 1, max_iter = 0, history_every = 100, walls = 0;
    double eps = 0.2, hdx = 1.2, tol = 1e-4, move_tol = 1e-2, perturb = 0.5;
    const char *kernel = "quintic", *out = NULL, *in = NULL, *box_text = NULL;
    cli_cache cache = {NULL, 0};
    cli_opt opts[] = {
        {"--kind", CLI_CHOICE, &kind_index, "K", "particle arrangement (required)",
         consph_layout_names(), 0, 0, 0},
        {"--dim", CLI_INT, &dim, "D", "dimension (required)", NULL, 1, 3, 0},
        {"--nx", CLI_INT, &nx, "N", "particles per axis, N^D in all (required)", NULL, 1, 100000,
         0},
        {"--periodic", CLI_CHOICE, &periodic_index, "P",
         "whether the unit box is periodic on every axis (default yes)", "yes,no", 0, 0, 0},
        {"--seed", CLI_INT, &seed, "S", "random seed, for random and the packed kinds (default 1)",
         NULL, 0, 9007199254740991.0, 0},
        {"--eps", CLI_DOUBLE, &eps, "E", "random: perturbation factor ε (default 0.2)", NULL, 0.0,
         2.0, 0},
        {"--kernel", CLI_STRING, &kernel, "K",
         "kernel of the density statistics, of packed's packing and of packed-polished's density "
         "target (default quintic)",
         NULL, 0, 0, 0},
        {"--hdx", CLI_DOUBLE, &hdx, "R", "h/Δs for that kernel (default 1.2)", NULL, 0.01, 10.0, 0},
        {"--perturb", CLI_DOUBLE, &perturb, "A",
         "packed kinds: initial perturbation amplitude in Δs (default 0.5)", NULL, 0.0, 0.5, 0},
        {"--tol", CLI_DOUBLE, &tol, "T",
         "packed-polished: stop once max|rho/rho0-1| < T (default 1e-4)", NULL, 1e-15, 1.0, 0},
        {"--move-tol", CLI_DOUBLE, &move_tol, "T",
         "packed: stop once 100 max|u| dt/h <= T at a test (default 1e-2, as [51]'s code)", NULL,
         1e-15, 100.0, 0},
        {"--walls", CLI_INT, &walls, "L",
         "packed: pack inside a frozen container of L lattice layers around the box (PySPH's "
         "create_frozen_container; the authors' packed files), then return the particles in "
         "the periodic box; 0 packs periodically (default 0); else at least half the kernel's "
         "support in Δs (quintic, 1.2: 2)",
         NULL, 0, 8, 0},
        {"--max-iter", CLI_INT, &max_iter, "M",
         "packed kinds: iteration cap (default 40000 packed, 5000 packed-polished)", NULL, 0,
         100000000, 0},
        {"--history-every", CLI_INT, &history_every, "K",
         "packed kinds: print the density spread every K iterations, 0 never (default 100)", NULL,
         0, 100000000, 0},
        {"--out", CLI_OUT_PATH, &out, "FILE", "write the particles; format by extension",
         ".vtu,.csv", 0, 0, 0},
        {"--vtu-encoding", CLI_CHOICE, &encoding_index, "E",
         "how a .vtu --out stores its arrays (default zlib)", consph_vtu_encoding_names(), 0, 0, 0},
        {"--in", CLI_STRING, &in, "FILE",
         "read particles (.csv or .vtu) instead of generating them; with --out: convert", NULL, 0,
         0, 0},
        {"--box", CLI_STRING, &box_text, "x0:x1,y0:y1[,z0:z1]",
         "with --in: the domain (default: the file's box)", NULL, 0, 0, 0},
        CLI_CACHE_OPTS(cache),
    };
    cli_command cmd = {
        "layout",
        "Generate a particle arrangement in the unit box, print its count, minimum spacing and\n"
        "density spread, and optionally write it.",
        "consph layout --kind K --dim D --nx N [options] | consph layout --in FILE [--out FILE2]",
        layout_details,
        opts,
        (int)(sizeof opts / sizeof opts[0]),
        0,
        NULL,
    };
    const int nopts = cmd.nopts;
    int rc = cli_parse(&cmd, argc, argv);
    if (rc == 1) return 0;
    if (rc) return rc;
    if ((rc = cli_cache_apply(&cmd, &cache))) return rc;

    consph_particle_format out_fmt = CONSPH_FORMAT_CSV;
    if (out) consph_particle_format_from_path(out, &out_fmt);
    if (opt_given(opts, nopts, "--vtu-encoding") && (!out || out_fmt != CONSPH_FORMAT_VTU))
        return cli_error(&cmd,
                         "option --vtu-encoding: only with a .vtu --out; allowed: --out FILE.vtu");
    consph_vtu_encoding enc = (consph_vtu_encoding)encoding_index;
    if (opt_given(opts, nopts, "--in")) {
        static const char *const generator_only[] = {
            "--kind", "--nx",       "--seed",     "--eps",           "--perturb",
            "--tol",  "--move-tol", "--max-iter", "--history-every", "--walls"};
        for (size_t k = 0; k < sizeof generator_only / sizeof generator_only[0]; ++k)
            if (opt_given(opts, nopts, generator_only[k]))
                return cli_error(&cmd, "option %s: not with --in (the file is the particles)",
                                 generator_only[k]);
        consph_kernel_id kid;
        if (consph_kernel_lookup(kernel, &kid) != CONSPH_OK || consph_kernel_info_get(kid)->tensor)
            return cli_error(&cmd, "option --kernel: '%s' is not a radial kernel; allowed: %s",
                             kernel, consph_kernel_names());
        return layout_from_file(&cmd, in, out, opt_given(opts, nopts, "--dim") ? dim : 0, box_text,
                                opt_given(opts, nopts, "--periodic"), periodic_index == 0, kernel,
                                hdx, enc);
    }
    if (box_text)
        return cli_error(&cmd, "option --box: only with --in (layouts fill the unit box)");
    if (!opt_given(opts, nopts, "--kind"))
        return cli_error(&cmd, "option --kind is required; allowed: %s", consph_layout_names());
    if (!opt_given(opts, nopts, "--dim"))
        return cli_error(&cmd, "option --dim is required; allowed: integer 1..3");
    if (!opt_given(opts, nopts, "--nx"))
        return cli_error(&cmd, "option --nx is required; allowed: integer 1..100000");
    consph_layout_kind kind = (consph_layout_kind)kind_index;
    if ((rc = cli_check_nx(&cmd, nx, dim))) return rc;
    const int packed = kind == CONSPH_LAYOUT_PACKED || kind == CONSPH_LAYOUT_PACKED_POLISHED;
    if (opt_given(opts, nopts, "--seed") && kind != CONSPH_LAYOUT_RANDOM && !packed)
        return cli_error(&cmd,
                         "option --seed applies only to --kind random, packed or packed-polished");
    if (opt_given(opts, nopts, "--eps") && kind != CONSPH_LAYOUT_RANDOM)
        return cli_error(&cmd, "option --eps applies only to --kind random");
    static const char *const packed_only[] = {"--perturb", "--max-iter", "--history-every"};
    for (size_t k = 0; k < sizeof packed_only / sizeof packed_only[0]; ++k)
        if (opt_given(opts, nopts, packed_only[k]) && !packed)
            return cli_error(&cmd, "option %s applies only to --kind packed or packed-polished",
                             packed_only[k]);
    if (opt_given(opts, nopts, "--tol") && kind != CONSPH_LAYOUT_PACKED_POLISHED)
        return cli_error(&cmd, "option --tol applies only to --kind packed-polished");
    if (opt_given(opts, nopts, "--move-tol") && kind != CONSPH_LAYOUT_PACKED)
        return cli_error(&cmd, "option --move-tol applies only to --kind packed");
    if (opt_given(opts, nopts, "--walls") && kind != CONSPH_LAYOUT_PACKED)
        return cli_error(&cmd, "option --walls applies only to --kind packed");
    consph_kernel_id kernel_id;
    if (consph_kernel_lookup(kernel, &kernel_id) != CONSPH_OK)
        return cli_error(&cmd, "option --kernel: unknown value '%s'; allowed: %s", kernel,
                         consph_kernel_names());
    if (packed && consph_kernel_info_get(kernel_id)->tensor)
        return cli_error(&cmd,
                         "option --kernel: '%s' is a tensor-product remeshing kernel; --kind "
                         "%s needs a radial kernel",
                         kernel, consph_layout_name(kind));
    /* The frozen container is 2·walls layers thick across the enlarged box's seam: at least the
     * kernel's support (src/layout/packing.c). */
    const int min_walls = (int)ceil(0.5 * consph_kernel_info_get(kernel_id)->support * hdx);
    if (walls > 0 && walls < min_walls)
        return cli_error(&cmd,
                         "option --walls: %ld layers are thinner than the support of %s at h/Δs "
                         "%g; allowed: 0 or %d..8",
                         walls, kernel, hdx, min_walls);
    int periodic = periodic_index == 0;
    if (packed && !periodic)
        return cli_error(&cmd,
                         "option --periodic: --kind %s needs a periodic box; allowed: "
                         "yes",
                         consph_layout_name(kind));

    consph_layout_params lp = consph_layout_defaults(kind, (int)dim, (size_t)nx);
    lp.box = consph_box_unit((int)dim, periodic);
    lp.seed = (uint64_t)seed;
    lp.eps = eps;
    lp.packing.kernel = kernel;
    lp.packing.hdx = hdx;
    lp.packing.perturb = perturb;
    lp.packing.tol = tol;
    lp.packing.move_tol = move_tol;
    lp.packing.walls = (int)walls;
    if (opt_given(opts, nopts, "--max-iter")) lp.packing.max_iter = (int)max_iter;
    lp.packing.history_every = (int)history_every;

    consph_particles p;
    consph_packing_report report;
    rc = consph_layout_generate(&lp, &p, &report);
    if (rc) {
        fprintf(stderr, "consph layout: %s\n", consph_last_error());
        return rc == CONSPH_EINVAL ? CLI_EXIT_USAGE : 1;
    }
    printf("kind %s, dim %ld, nx %ld, particles %zu, spacing %.6g, unit box%s\n",
           consph_layout_name(kind), dim, nx, p.n, p.spacing, periodic ? " periodic" : "");
    if (packed) print_report(&report, &lp);

    if (print_stats(&p, kernel, hdx) != CONSPH_OK) {
        consph_packing_report_free(&report);
        consph_particles_free(&p);
        return 1;
    }
    if (out) {
        rc = consph_write_particles_enc(out, &p, enc);
        if (rc) {
            fprintf(stderr, "consph layout: %s\n", consph_last_error());
        } else {
            printf("wrote %s\n", out);
        }
    }
    consph_packing_report_free(&report);
    consph_particles_free(&p);
    return rc ? 1 : 0;
}
