/* The consph subcommands; each lives in apps/cmd_<name>.c and returns the process exit status. */
#ifndef CONSPH_APPS_COMMANDS_H
#define CONSPH_APPS_COMMANDS_H

int cmd_kernels(int argc, char **argv);
int cmd_kernel(int argc, char **argv);
int cmd_layout(int argc, char **argv);
int cmd_approx(int argc, char **argv);
int cmd_study(int argc, char **argv);
int cmd_wasserstein(int argc, char **argv);
int cmd_run(int argc, char **argv);

#endif
