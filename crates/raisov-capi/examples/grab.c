/* Grasp the top of a block of tissue through raisov's C ABI and render the tool force to a
 * haptic device at 1 kHz on its own thread, through a haptic proxy: the simulation thread
 * steps frames (5 ms of wall time each) with the grasp following the device; the device
 * thread reads the force extrapolated to its own position, never waiting for a frame. The
 * device here is scripted: it rises 4 mm over 0.2 s.
 *
 *   cargo build --release -p raisov-capi
 *   cc crates/raisov-capi/examples/grab.c -I crates/raisov-capi/include \
 *      target/release/libraisov_capi.a -lm -lpthread -ldl -o target/grab-c
 *   target/grab-c [scenario.toml]     (default: writes a small box scenario to target/)
 *
 * Exits non-zero if a call fails or the physics is off (checks at the end). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "raisov.h"

static const char *SCENARIO =
    "gravity = [0, 0, -9.81]\n"
    "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n"
    "[material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n"
    "[[fix]]\nplane = { point = [0, 0, 0], normal = [0, 0, 1] }\n"
    "[run]\nduration = 1.0\n";

static const double MAX_FORCE = 2.0;    /* the device's limit (N) */
static const double MAX_DISTANCE = 0.005; /* the linear model's trusted radius (m) */

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The scripted device: starts at the grasp point x0 and rises 4 mm over 0.2 s. */
static double X0[3], T0;
static void device_at(double x[3]) {
    double s = (now_s() - T0) / 0.2;
    x[0] = X0[0];
    x[1] = X0[1];
    x[2] = X0[2] + 0.004 * (s < 1.0 ? s : 1.0);
}

struct Device {
    RaisovHaptic *haptic;
    atomic_int stop;
    long ticks, clamped, bad;
};

/* The device thread: one force per millisecond. */
static void *device_loop(void *arg) {
    struct Device *d = arg;
    const struct timespec ms = {0, 1000000};
    while (!atomic_load(&d->stop)) {
        nanosleep(&ms, NULL);
        double x[3], f[3];
        device_at(x);
        int flags = raisov_haptic_force_at(d->haptic, x, f);
        double n = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        /* ... here the force goes to the device ... */
        if (flags < 0 || !(flags & RAISOV_HAPTIC_HELD) || !(n <= MAX_FORCE * (1 + 1e-12)))
            d->bad++;
        if (flags & RAISOV_HAPTIC_FORCE_CLAMPED) d->clamped++;
        d->ticks++;
    }
    return NULL;
}

static int fail(RaisovSim *sim, const char *what) {
    fprintf(stderr, "%s: %s\n", what, raisov_last_error());
    raisov_sim_free(sim);
    return 1;
}

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "target/grab-c-scenario.toml";
    if (argc <= 1) {
        FILE *f = fopen(path, "w");
        if (!f || fputs(SCENARIO, f) < 0 || fclose(f) != 0) {
            fprintf(stderr, "cannot write %s\n", path);
            return 1;
        }
    }
    RaisovSim *sim = raisov_sim_from_file(path);
    if (!sim) return fail(NULL, "error");
    const double point[3] = {0.02, 0.02, 0.05};
    int64_t g = raisov_sim_grab(sim, point, 0.011);
    if (g < 0 || raisov_sim_grab_position(sim, g, X0) != 0) return fail(sim, "grab");
    struct Device dev = {.haptic = raisov_sim_haptic(sim, g, MAX_FORCE, MAX_DISTANCE)};
    if (!dev.haptic) return fail(sim, "haptic proxy");
    atomic_init(&dev.stop, 0);

    /* The simulation loop: the grasp follows the device, 5 ms of stepping per frame, for
     * 0.3 s; each frame publishes the grasp's position, force and stiffness to the proxy. */
    pthread_t thread;
    T0 = now_s();
    if (pthread_create(&thread, NULL, device_loop, &dev) != 0) return fail(sim, "thread");
    int frames = 0;
    while (now_s() - T0 < 0.3) {
        double x[3];
        device_at(x);
        if (raisov_sim_move_grab(sim, g, x) != 0 || raisov_sim_step_ms(sim, 5.0) < 0) break;
        frames++;
    }
    atomic_store(&dev.stop, 1);
    pthread_join(thread, NULL);
    /* Let the tissue settle under the lifted grasp. */
    for (int k = 0; k < 20; k++)
        if (raisov_sim_step_cycles(sim, 8) != 1) return fail(sim, "frame");
    printf("%d frames, %ld device ticks in %.2f s (%ld forces clamped at %.1f N)\n", frames,
           dev.ticks, now_s() - T0, dev.clamped, MAX_FORCE);

    /* The proxy's newest frame, and the extrapolation 0.1 mm above it. */
    RaisovHapticFrame fr;
    double f[3], up[3], fu[3];
    if (raisov_haptic_frame(dev.haptic, &fr) != 0 || raisov_sim_grab_force(sim, g, f) != 0)
        return fail(sim, "frame");
    int at = raisov_haptic_force_at(dev.haptic, fr.position, fu);
    int same = at == RAISOV_HAPTIC_HELD && fu[0] == f[0] && fu[1] == f[1] && fu[2] == f[2];
    up[0] = fr.position[0];
    up[1] = fr.position[1];
    up[2] = fr.position[2] + 1e-4;
    raisov_haptic_force_at(dev.haptic, up, fu);
    double k_delta = 0.0; /* |f(x + d) - f - K d|, d = 0.1 mm along z */
    for (int i = 0; i < 3; i++) k_delta += fabs(fu[i] - f[i] - fr.stiffness[3 * i + 2] * 1e-4);
    printf("force on the tool [%+.5f, %+.5f, %+.5f] N, stiffness diagonal [%.1f, %.1f, %.1f] "
           "N/m; 0.1 mm higher: %+.5f N\n",
           f[0], f[1], f[2], fr.stiffness[0], fr.stiffness[4], fr.stiffness[8], fu[2]);

    /* What a renderer draws: the surface triangles and their vertices now. */
    int64_t nv = raisov_sim_surface_vertex_count(sim), nt = raisov_sim_surface_triangle_count(sim);
    double *xs = malloc(sizeof(double) * 3 * (size_t)(nv > 0 ? nv : 1));
    uint32_t *tri = malloc(sizeof(uint32_t) * 3 * (size_t)(nt > 0 ? nt : 1));
    if (!xs || !tri || raisov_sim_surface_positions(sim, xs, 3 * (size_t)nv) != 3 * nv ||
        raisov_sim_surface_triangles(sim, tri, 3 * (size_t)nt) != 3 * nt) {
        free(xs);
        free(tri);
        return fail(sim, "surface");
    }
    int indices_ok = 1;
    double top = xs[2];
    for (int64_t i = 0; i < 3 * nt; i++) indices_ok &= tri[i] < (uint64_t)nv;
    for (int64_t a = 1; a < nv; a++)
        if (xs[3 * a + 2] > top) top = xs[3 * a + 2];
    printf("surface: %lld triangles over %lld vertices, highest at z = %.4f m\n", (long long)nt,
           (long long)nv, top);
    free(xs);
    free(tri);

    /* Released: the device feels nothing. A spring grasp with a negative stiffness: an error. */
    double zero[3] = {1, 1, 1};
    int released = raisov_sim_release(sim, g) == 0 &&
                   raisov_haptic_force_at(dev.haptic, up, zero) == 0 && zero[2] == 0.0;
    int refused = raisov_sim_grab_spring(sim, point, 0.004, -1.0) == -1;
    raisov_sim_free(sim);
    raisov_haptic_free(dev.haptic);

    const char *why = NULL;
    if (dev.ticks < 10 || dev.bad) why = "the device loop read too few or bad forces";
    else if (!(f[2] < 0.0)) why = "the lifted tissue should pull the tool down";
    else if (!(fr.stiffness[0] < 0.0 && fr.stiffness[4] < 0.0 && fr.stiffness[8] < 0.0))
        why = "the grasp stiffness should resist every move (negative diagonal)";
    else if (!same) why = "at the frame's position the proxy should give the frame's force";
    else if (!(k_delta < 1e-12 && fu[2] < f[2])) why = "0.1 mm higher should add K d";
    else if (!indices_ok || !(top > 0.0435)) why = "the surface should be lifted, indices valid";
    else if (!released || !refused) why = "release or the spring-grasp check failed";
    if (why) {
        fprintf(stderr, "%s\n", why);
        return 1;
    }
    return 0;
}
