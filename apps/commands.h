/* The consph subcommands; each lives in apps/cmd_<name>.c and returns the process exit status. */
#ifndef CONSPH_APPS_COMMANDS_H
#define CONSPH_APPS_COMMANDS_H

int cmd_kernels(int argc, char **argv);
int cmd_kernel(int argc, char **argv);
int cmd_layout(int argc, char **argv);
int cmd_approx(int argc, char **argv);
int cmd_study(int argc, char **argv);
/* 1 once cmd_study called the study run, whose first collective call under MPI agrees with every
 * rank that it may start; a rank that stopped before makes that call in main (apps/consph.c). */
extern int cmd_study_started;
int cmd_wasserstein(int argc, char **argv);
/* The same for `consph run`: 1 once every rank made its solver and agrees to decompose it. */
extern int cmd_run_started;
int cmd_run(int argc, char **argv);

#endif
