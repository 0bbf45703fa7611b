/* raisov.h: a small C ABI over raisov's frame-loop API (crate raisov-capi).
 *
 * Link the static library (target/release/libraisov_capi.a) with -lm -lpthread -ldl, or the
 * shared one (libraisov_capi.so). Units are SI: metres, newtons, seconds.
 *
 * Errors: a call that fails returns NULL or -1 (see each function), and raisov_last_error()
 * gives the message of the last failure on the calling thread. No call panics or aborts on bad
 * input; NULL pointers are reported as errors, and a caller buffer too small for what a call
 * copies is an error that names the room needed (nothing is written).
 *
 * Threads: a RaisovSim is not thread-safe: use it from one thread at a time. A RaisovHaptic
 * is: any thread may read it at any rate, concurrently with the simulation's calls on another
 * thread; a read never waits for the simulation, and it stays valid after raisov_sim_free.
 *
 * Sign convention: raisov_sim_grab_force writes the force the tissue exerts on the tool,
 * sum over the grasped nodes of (external load - internal force); lifting a patch gives a
 * force pointing down. raisov_sim_grab_stiffness writes K[i][j] = d force_i / d position_j.
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

/* An opaque haptic proxy of one grasp (raisov_sim_haptic). */
typedef struct RaisovHaptic RaisovHaptic;

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

/* One frame of `ms` milliseconds of wall time: steps until the time has passed (at least
 * one). Returns as raisov_sim_step_cycles; -1 also for `ms` not finite and >= 0. */
int32_t raisov_sim_step_ms(RaisovSim *sim, double ms);

/* Copy the node positions (m, x y z per node) into `out`, which holds `len` doubles
 * (at least 3 * raisov_sim_num_nodes). Returns the number of doubles written, or -1. */
int64_t raisov_sim_positions(const RaisovSim *sim, double *out, size_t len);

/* Write the force the tissue exerts on the tool of `grab` (N) into `out[3]`. 0, or -1. */
int32_t raisov_sim_grab_force(const RaisovSim *sim, int64_t grab, double *out);

/* Write where grasp `grab` holds its nodes now (m) into `out[3]`. 0, or -1. */
int32_t raisov_sim_grab_position(const RaisovSim *sim, int64_t grab, double *out);

/* Write the stiffness of grasp `grab` into `out[9]` (N/m, row-major): K[i][j] = d force_i /
 * d position_j, the change of the tool force when the grasp moves and the free nodes return
 * to equilibrium (three linear solves). Not the spring stiffness of
 * raisov_sim_set_grab_stiffness. 0, or -1. */
int32_t raisov_sim_grab_stiffness(RaisovSim *sim, int64_t grab, double *out);

/* The surface a renderer draws: the visual surface's vertices when the scenario meshed one
 * ([mesh] surface), else the mesh's nodes; its triangles counter-clockwise seen from outside
 * (a tetrahedral mesh's boundary faces, a membrane's own triangles). The triangles change
 * only when the body is cut (raisov_sim_cut: read the counts again); the positions change
 * every frame. */

/* Number of surface vertices, or -1. */
int64_t raisov_sim_surface_vertex_count(const RaisovSim *sim);

/* Copy the surface vertex positions (m, x y z per vertex) into `out`, which holds `len`
 * doubles (at least 3 * raisov_sim_surface_vertex_count). The doubles written, or -1. */
int64_t raisov_sim_surface_positions(const RaisovSim *sim, double *out, size_t len);

/* Number of surface triangles, or -1. */
int64_t raisov_sim_surface_triangle_count(const RaisovSim *sim);

/* Copy the surface triangles (3 vertex indices each, 0-based) into `out`, which holds `len`
 * indices (at least 3 * raisov_sim_surface_triangle_count). The indices written, or -1. */
int64_t raisov_sim_surface_triangles(const RaisovSim *sim, uint32_t *out, size_t len);

/* Haptics. A device loop (about 1 kHz) runs beside the simulation's frames (tens of ms):
 * after every frame the simulation publishes to each proxy its grasp's position x_f, force
 * f_f and stiffness K (three linear solves per frame and proxy), and the device thread
 * renders, for its position x,
 *
 *     d = x - x_f, shortened to max_distance if longer (the linear model's trusted radius);
 *     f = f_f + K d, scaled down to max_force if larger (the device's limit).
 *
 * f is the force the tissue exerts on the tool: what the device renders on the hand. */

/* Levels whose split elements RaisovCutReport.split lists one by one. */
#define RAISOV_CUT_MAX_LEVELS 8

/* What raisov_sim_cut did. */
typedef struct RaisovCutReport {
    uint32_t levels;                        /* the simulation's levels (entries of split used,
                                             * at most RAISOV_CUT_MAX_LEVELS) */
    uint64_t split[RAISOV_CUT_MAX_LEVELS];  /* elements split per level, finest first */
    uint64_t split_total;                   /* elements split on every level */
    int64_t nodes;                          /* level 0's nodes after the cut */
    int64_t elements;                       /* level 0's elements after the cut */
    double seconds;                         /* wall time of the cut (s) */
} RaisovCutReport;

/* Cut the body with the blade the edge a[3]-b[3] (m) sweeps along sweep[3] (m): the quad with
 * corners a, b, b + sweep, a + sweep (a scalpel drawn from a to b on the surface, pushed
 * |sweep| deep along sweep), on every level (the virtual node algorithm). Node and element
 * counts change: read raisov_sim_num_nodes and the surface counts again. A blade that misses
 * changes nothing (split all zero). Writes *out (NULL: not wanted). 0, or -1 with nothing
 * changed: a degenerate blade, a membrane, loads that cannot be cut (pressure, traction,
 * timed loads, tools). */
int32_t raisov_sim_cut(RaisovSim *sim, const double *a, const double *b, const double *sweep,
                       RaisovCutReport *out);

/* One published frame. */
typedef struct RaisovHapticFrame {
    uint64_t seq;          /* publication number: 1, 2, ... */
    int32_t held;          /* 1 while the grasp is held; 0 after a release or raisov_sim_free */
    double position[3];    /* x_f (m) */
    double force[3];       /* f_f (N) */
    double stiffness[9];   /* K (N/m, row-major) */
    double time;           /* simulated time of the frame (s) */
    double age;            /* seconds since the frame was published */
} RaisovHapticFrame;

/* Flags returned by raisov_haptic_force_at. */
#define RAISOV_HAPTIC_HELD 1             /* the grasp is held (else the force is zero) */
#define RAISOV_HAPTIC_DISTANCE_CLAMPED 2 /* the device was beyond max_distance */
#define RAISOV_HAPTIC_FORCE_CLAMPED 4    /* the force was scaled down to max_force */

/* A haptic proxy of grasp `grab`, within `max_force` (N) and `max_distance` (m), each > 0
 * (INFINITY: no limit). It publishes the current frame at once. NULL on error. Free it with
 * raisov_haptic_free, before or after the simulation. */
RaisovHaptic *raisov_sim_haptic(RaisovSim *sim, int64_t grab, double max_force,
                                double max_distance);

/* Write the force at device position `x[3]` (m) from the newest frame into `out[3]` (N).
 * Returns the RAISOV_HAPTIC_* flags (0: no grasp held, a zero force), or -1 on error. Any
 * thread; never waits for the simulation. */
int32_t raisov_haptic_force_at(const RaisovHaptic *h, const double *x, double *out);

/* Write the newest published frame into `*out`. 0, or -1. Any thread. */
int32_t raisov_haptic_frame(const RaisovHaptic *h, RaisovHapticFrame *out);

/* Set the limits (as raisov_sim_haptic's). 0, or -1 (nothing changed). Any thread. */
int32_t raisov_haptic_set_limits(const RaisovHaptic *h, double max_force, double max_distance);

/* Free a haptic proxy; NULL is ignored. No other thread may use it during or after. */
void raisov_haptic_free(RaisovHaptic *h);

#ifdef __cplusplus
}
#endif

#endif /* RAISOV_H */
