/* A friction compensator built on the exported step: a simulated linear axis under PD
   control with and without the model's friction feedforward.

   Plant: a mass M (kg) driven by the motor force u against friction, M*a = u - F_fric,
   integrated with semi-implicit Euler on SUB sub-steps per controller sample. Its friction
   is the exported model itself, driven by the true motion (one jaxfric_state). Controller
   at TS seconds: u = M*a_r + Kp*(r - x) + Kd*(r_dot - v) [+ F_ff], where the feedforward
   F_ff is the exported model driven by the reference (a second jaxfric_state).
   Reference: r = A*sin(2*pi*t/PERIOD); the maximum |r - x| over the second period is
   printed (m), without and with the feedforward.

   Build (after `jaxfric export fit.json --c model/`):
     cc -O2 -std=c99 -Imodel examples/c_compensator.c model/jaxfric_model.c -lm -o axis
   Run: ./axis [A in m, default 1e-4] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "jaxfric_model.h"

#define M 10.0          /* kg */
#define TS 1e-3         /* controller sample time, s */
#define SUB 20          /* plant sub-steps per sample */
#define PERIOD 6.0      /* s */
#define WN (2.0 * 3.141592653589793 * 30.0) /* closed-loop bandwidth, rad/s */

static double max_error(double amp, int feedforward)
{
    jaxfric_state plant, ff;
    const double kp = M * WN * WN, kd = 2.0 * 0.7 * WN * M, h = TS / SUB;
    const double w = 2.0 * 3.141592653589793 / PERIOD;
    double x = 0.0, v = 0.0, f = 0.0, t = 0.0, worst = 0.0;
    long k, n = (long)(2.0 * PERIOD / TS);
    int j;
    jaxfric_init(&plant, 0.0, 0.0);
    jaxfric_init(&ff, 0.0, 0.0);
    for (k = 0; k < n; ++k) {
        double tk = k * TS;
        double r = amp * sin(w * tk), rd = amp * w * cos(w * tk), ra = -w * w * r;
        double f_ff = jaxfric_step(&ff, tk, r, rd);
        double u = M * ra + kp * (r - x) + kd * (rd - v) + (feedforward ? f_ff : 0.0);
        if (tk >= PERIOD && fabs(r - x) > worst) worst = fabs(r - x);
        for (j = 0; j < SUB; ++j) {
            v += h * (u - f) / M;
            x += h * v;
            t += h;
            f = jaxfric_step(&plant, t, x, v);
        }
    }
    return worst;
}

int main(int argc, char **argv)
{
    double amp = argc > 1 ? atof(argv[1]) : 1e-4;
    printf("amplitude %g m\n", amp);
    printf("max tracking error without friction feedforward: %.4g m\n", max_error(amp, 0));
    printf("max tracking error with friction feedforward:    %.4g m\n", max_error(amp, 1));
    return 0;
}
