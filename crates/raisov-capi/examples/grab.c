/* Grasp the top of a block of tissue through raisov's C ABI, lift it 4 mm over 10 frames and
 * print the force on the tool.
 *
 *   cargo build --release -p raisov-capi
 *   cc crates/raisov-capi/examples/grab.c -I crates/raisov-capi/include \
 *      target/release/libraisov_capi.a -lm -lpthread -ldl -o target/grab-c
 *   target/grab-c [scenario.toml]     (default: writes a small box scenario to target/) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "raisov.h"

static const char *SCENARIO =
    "gravity = [0, 0, -9.81]\n"
    "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n"
    "[material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n"
    "[[fix]]\nplane = { point = [0, 0, 0], normal = [0, 0, 1] }\n"
    "[run]\nduration = 1.0\n";

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
    if (!sim) {
        fprintf(stderr, "error: %s\n", raisov_last_error());
        return 1;
    }
    int64_t n = raisov_sim_num_nodes(sim);
    const double point[3] = {0.02, 0.02, 0.05};
    int64_t g = raisov_sim_grab(sim, point, 0.011);
    if (g < 0) {
        fprintf(stderr, "error: %s\n", raisov_last_error());
        raisov_sim_free(sim);
        return 1;
    }
    double force[3] = {0, 0, 0};
    for (int frame = 1; frame <= 10; frame++) {
        const double target[3] = {0.02, 0.02, 0.04 + 0.0004 * frame};
        if (raisov_sim_move_grab(sim, g, target) != 0 || raisov_sim_step_cycles(sim, 8) != 1 ||
            raisov_sim_grab_force(sim, g, force) != 0) {
            fprintf(stderr, "frame %d: %s\n", frame, raisov_last_error());
            raisov_sim_free(sim);
            return 1;
        }
        printf("frame %2d: lift %.1f mm, force on the tool [%+.5f, %+.5f, %+.5f] N\n", frame,
               0.4 * frame, force[0], force[1], force[2]);
    }
    /* A spring grasp of a corner of the top face: 50 N/m, its anchor lifted by 2 mm, 20 more
     * steps of the explicit dynamics (the tissue is still moving: the force is k times the
     * patch's lag behind the anchor, of either sign). */
    const double corner[3] = {0.036, 0.036, 0.05};
    int64_t s = raisov_sim_grab_spring(sim, corner, 0.004, 50.0);
    double spring[3] = {0, 0, 0}, lifted[3] = {0, 0, 0};
    if (s < 0 || raisov_sim_grab_position(sim, s, lifted) != 0) {
        fprintf(stderr, "spring grasp: %s\n", raisov_last_error());
        raisov_sim_free(sim);
        return 1;
    }
    lifted[2] += 0.002;
    if (raisov_sim_move_grab(sim, s, lifted) != 0 ||
        raisov_sim_step_cycles(sim, 20) != 1 || raisov_sim_grab_force(sim, s, spring) != 0) {
        fprintf(stderr, "spring grasp: %s\n", raisov_last_error());
        raisov_sim_free(sim);
        return 1;
    }
    printf("spring grasp: force on the tool [%+.5f, %+.5f, %+.5f] N\n", spring[0], spring[1],
           spring[2]);
    if (raisov_sim_grab_spring(sim, corner, 0.004, -1.0) != -1) {
        fprintf(stderr, "a negative stiffness must be an error\n");
        raisov_sim_free(sim);
        return 1;
    }
    double *x = malloc(sizeof(double) * 3 * (size_t)n);
    if (!x || raisov_sim_positions(sim, x, 3 * (size_t)n) != 3 * n) {
        fprintf(stderr, "positions: %s\n", x ? raisov_last_error() : "out of memory");
        free(x);
        raisov_sim_free(sim);
        return 1;
    }
    double top = x[2];
    for (int64_t a = 1; a < n; a++)
        if (x[3 * a + 2] > top) top = x[3 * a + 2];
    printf("%lld nodes, highest at z = %.4f m\n", (long long)n, top);
    free(x);
    raisov_sim_free(sim);
    if (!(force[2] < 0.0) || !isfinite(spring[0] + spring[1] + spring[2])) {
        fprintf(stderr, "the lifted tissue should pull the tool down, the spring be finite\n");
        return 1;
    }
    return 0;
}
