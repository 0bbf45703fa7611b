/* raisov.h: a small C ABI over raisov's frame-loop API (crate raisov-capi).
 *
 * Link the static library (target/release/libraisov_capi.a) with -lm -lpthread -ldl, or the
 * shared one (libraisov_capi.so). Units are SI: metres, newtons, seconds.
 *
 * Errors: a call that fails returns NULL or -1 (see each function), and raisov_last_error()
 * gives the message of the last failure on the calling thread. No call panics or aborts on bad
 * input; NULL pointers are reported as errors. A RaisovSim is not thread-safe: use it from one
 * thread at a time.
 *
 * Sign convention: raisov_sim_grab_force writes the force the tissue exerts on the tool,
 * sum over the grasped nodes of (external load - internal force); lifting a patch gives a
 * force pointing down.
 */
#ifndef RAISOV_H
#define RAISOV_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* An opaque simulation. */
typedef struct RaisovSim RaisovSim;

/* The message of the last failed call on this thread (UTF-8; "" when none failed). Valid until
 * the next failing call on this thread. */
const char *raisov_last_error(void);

/* Load a scenario file (raisov's TOML format). NULL on error. */
RaisovSim *raisov_sim_from_file(const char *path);

/* Free a simulation; NULL is ignored. */
void raisov_sim_free(RaisovSim *sim);

/* Number of nodes, or -1 on error. */
int64_t raisov_sim_num_nodes(const RaisovSim *sim);

/* Grasp the surface patch within `radius` (m) of the surface point nearest `point[3]` (m).
 * Returns the grasp's handle (> 0), or -1 on error. */
int64_t raisov_sim_grab(RaisovSim *sim, const double *point, double radius);

/* Grasp the surface near `point[3]` (m) within `radius` (m) by springs of total stiffness
 * `stiffness` (N/m, spread over the grasped nodes by mass; the nodes stay free, so the tissue
 * can lag behind the tool). The grasp's handle (> 0), or -1 on error. */
int64_t raisov_sim_grab_spring(RaisovSim *sim, const double *point, double radius,
                               double stiffness);

/* Make grasp `grab` a spring grasp of total stiffness `stiffness` (N/m). 0, or -1. */
int32_t raisov_sim_set_grab_stiffness(RaisovSim *sim, int64_t grab, double stiffness);

/* Move grasp `grab` to `target[3]` (m) over the next frame. 0, or -1 on error. */
int32_t raisov_sim_move_grab(RaisovSim *sim, int64_t grab, const double *target);

/* Let go of grasp `grab`. 0, or -1 on error. */
int32_t raisov_sim_release(RaisovSim *sim, int64_t grab);

/* One frame of `cycles` stepper steps. 1: accepted; 0: rejected (the state is the one before
 * the frame, raisov_last_error() says why); -1: error. */
int32_t raisov_sim_step_cycles(RaisovSim *sim, uint32_t cycles);

/* Copy the node positions (m, x y z per node) into `out`, which holds `len` doubles
 * (at least 3 * raisov_sim_num_nodes). Returns the number of doubles written, or -1. */
int64_t raisov_sim_positions(const RaisovSim *sim, double *out, size_t len);

/* Write the force the tissue exerts on the tool of `grab` (N) into `out[3]`. 0, or -1. */
int32_t raisov_sim_grab_force(const RaisovSim *sim, int64_t grab, double *out);

/* Write where grasp `grab` holds its nodes now (m) into `out[3]`. 0, or -1. */
int32_t raisov_sim_grab_position(const RaisovSim *sim, int64_t grab, double *out);

#ifdef __cplusplus
}
#endif

#endif /* RAISOV_H */
