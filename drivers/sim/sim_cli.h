/* The subcommands of descatter-sim (drivers/sim/descatter_sim.c dispatches). Each returns the
 * exit status: 0 done, 1 failed (message on stderr), 2 bad usage. */
#pragma once

int ds_sim_render_main (int argc, char **argv);
int ds_sim_describe_main (int argc, char **argv);
