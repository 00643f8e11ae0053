/* What src/io/stop.c needs of the outfile registry; not part of the public API. */
#ifndef CONSPH_IO_OUTFILE_INTERNAL_H
#define CONSPH_IO_OUTFILE_INTERNAL_H

/* Unlinks the temporary file of every consph_outfile still open. Async-signal-safe: for a
 * signal handler that is about to end the process. */
void consph_outfile_remove_temps(void);

#endif
