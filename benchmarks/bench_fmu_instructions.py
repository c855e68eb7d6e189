"""Instructions per FMI call of the TrailerTrain FMU, counted by valgrind (issue 14).

Timings on a shared 2-core machine move by 2x with the other processes' load; instruction
counts do not. A small C driver (compiled here) loads the FMU's library and calls one function
in a loop; ``valgrind --tool=callgrind --toggle-collect=FUNCTION`` counts the instructions
executed inside that function, and the difference between two loop lengths gives the count per
call (set-up and warm-up drop out). Printed per n:

- fmi2GetReal of every Real output: in Initialization Mode, right after a step, and after an
  input set (the outputs recomputed once); fmi2GetBoolean of every Boolean output after a step;
- fmi2DoStep of 5 ms in slip_mode 0 (rolling) and in slip_mode 1 with every wheel sliding (the
  robot whips its yaw rate +-2 rad/s at 1 Hz on mu = 0.0005, as in bench_slip.py), and their
  ratio.

Targets judged: a read of all outputs costs O(values + n), well below a step; the sliding step
grows linearly in n (instructions per trailer printed).

Run: python benchmarks/bench_fmu_instructions.py [--sizes 3 10 50]   (needs valgrind and cc)
"""

import argparse
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import fmpy
from fmpy import extract, read_model_description

from pushtrain.fmu.build import build_fmu

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dlfcn.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c,
                   fmi2String m, ...) {
    (void)e; (void)n; (void)c;
    if (s != fmi2OK) fprintf(stderr, "FMU: %s\n", m);
}

static int read_refs(const char *path, fmi2ValueReference *refs) {
    FILE *f = fopen(path, "r");
    int n = 0;
    while (f != NULL && fscanf(f, "%u", &refs[n]) == 1) n++;
    if (f != NULL) fclose(f);
    return n;
}

/* driver LIB GUID REALS BOOLEANS MU_REFS INPUTS WHAT CALLS
   WHAT: init_get, get, set_get, get_bool, step0, step_slide */
int main(int argc, char **argv) {
    static fmi2ValueReference reals[8192], flags[256], mus[256], inputs[8];
    static fmi2Real out[8192], values[256];
    static fmi2Boolean flag_out[256];
    void *lib;
    fmi2Component c;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    int n_reals, n_flags, n_mus, calls, k;
    const char *what;
    if (argc != 9) return 2;
    lib = dlopen(argv[1], RTLD_NOW);
    if (lib == NULL) { fprintf(stderr, "%s\n", dlerror()); return 1; }
#define F(name) fmi2##name##TYPE *name = (fmi2##name##TYPE *)dlsym(lib, "fmi2" #name)
    F(Instantiate); F(SetupExperiment); F(EnterInitializationMode); F(ExitInitializationMode);
    F(SetReal); F(SetInteger); F(GetReal); F(GetBoolean); F(DoStep);
    n_reals = read_refs(argv[3], reals);
    n_flags = read_refs(argv[4], flags);
    n_mus = read_refs(argv[5], mus);
    read_refs(argv[6], inputs); /* v_cmd, w_cmd, slip_mode, robot_alpha_max */
    what = argv[7];
    calls = atoi(argv[8]);
    c = Instantiate("driver", fmi2CoSimulation, argv[2], "file:///tmp", &cb, fmi2False, fmi2False);
    if (c == NULL) return 1;
    SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    EnterInitializationMode(c);
    if (strcmp(what, "init_get") == 0) {
        for (k = 0; k < calls; k++) GetReal(c, reals, n_reals, out);
        return 0;
    }
    if (strcmp(what, "step_slide") == 0) {
        fmi2Integer one = 1;
        fmi2Real alpha = 50.0;
        SetInteger(c, &inputs[2], 1, &one);
        SetReal(c, &inputs[3], 1, &alpha);
        for (k = 0; k < n_mus; k++) values[k] = 0.0005;
        SetReal(c, mus, n_mus, values);
    }
    if (ExitInitializationMode(c) != fmi2OK) return 1;
    DoStep(c, 0.0, 0.005, fmi2True);
    for (k = 0; k < calls; k++) {
        if (strcmp(what, "get") == 0) {
            GetReal(c, reals, n_reals, out);
        } else if (strcmp(what, "set_get") == 0) {
            fmi2Real w = 0.01 * (k % 2);
            SetReal(c, &inputs[1], 1, &w);
            GetReal(c, reals, n_reals, out);
        } else if (strcmp(what, "get_bool") == 0) {
            GetBoolean(c, flags, n_flags, flag_out);
        } else {
            fmi2Real command[2] = {-0.05, 2.0 * sin(2.0 * M_PI * (k + 1) * 0.005)};
            SetReal(c, inputs, 2, command);
            if (DoStep(c, (k + 1) * 0.005, 0.005, fmi2True) != fmi2OK) return 1;
        }
    }
    return 0;
}
"""


def compile_driver(work: Path) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise SystemExit("needs a C compiler (cc)")
    (work / "driver.c").write_text(DRIVER)
    driver = work / "driver"
    subprocess.run([compiler, "-O2", "-D_GNU_SOURCE", f"-I{Path(fmpy.__file__).parent / 'c-code'}",
                    str(work / "driver.c"), "-o", str(driver), "-ldl", "-lm"], check=True)
    return driver


def instructions(driver: Path, args: list[str], what: str, function: str, calls: int) -> int:
    """Instructions executed inside ``function`` over a run of ``calls`` calls."""
    done = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                           f"--toggle-collect={function}", str(driver), *args, what, str(calls)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"driver {what} failed:\n{done.stderr[-2000:]}")
    match = re.search(r"Collected : (\d+)", done.stderr)
    if match is None:
        raise RuntimeError(f"no callgrind total in:\n{done.stderr[-2000:]}")
    return int(match.group(1))


def per_call(driver, args, what, function, few, many) -> float:
    return (instructions(driver, args, what, function, many)
            - instructions(driver, args, what, function, few)) / (many - few)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[3, 10, 50])
    args = parser.parse_args()
    if shutil.which("valgrind") is None:
        raise SystemExit("needs valgrind (apt-get install valgrind)")
    work = Path(tempfile.mkdtemp(prefix="bench_fmu_instructions-"))
    try:
        driver = compile_driver(work)
        print("instructions per call (valgrind callgrind)")
        print(f"{'n':>3} {'Reals':>6} {'getReal init':>13} {'after step':>11} {'after set':>10} "
              f"{'getBoolean':>11} {'doStep 0':>10} {'doStep slide':>13} {'slide / 0':>10} "
              f"{'slide / n':>10}")
        for n in args.sizes:
            fmu = build_fmu(n)
            md = read_model_description(str(fmu))
            unzipdir = Path(extract(str(fmu), unzipdir=str(work / f"n{n}")))
            vr = {v.name: v.valueReference for v in md.modelVariables}
            lists = {
                "reals": [v.valueReference for v in md.modelVariables
                          if v.causality == "output" and v.type == "Real"],
                "flags": [v.valueReference for v in md.modelVariables
                          if v.causality == "output" and v.type == "Boolean"],
                "mus": [vr[f"mu[{i}]"] for i in range(1, n + 1)],
                "inputs": [vr["v_cmd"], vr["w_cmd"], vr["slip_mode"], vr["robot_alpha_max"]],
            }
            for name, refs in lists.items():
                (work / f"{name}{n}.txt").write_text(" ".join(map(str, refs)))
            call_args = [str(unzipdir / "binaries" / "linux64" / "TrailerTrain.so"), md.guid,
                         *(str(work / f"{name}{n}.txt") for name in lists)]
            init = per_call(driver, call_args, "init_get", "fmi2GetReal", 10, 60)
            get = per_call(driver, call_args, "get", "fmi2GetReal", 10, 60)
            set_get = per_call(driver, call_args, "set_get", "fmi2GetReal", 10, 60)
            flags = per_call(driver, call_args, "get_bool", "fmi2GetBoolean", 10, 60)
            step0 = per_call(driver, call_args, "step0", "fmi2DoStep", 100, 300)
            slide = per_call(driver, call_args, "step_slide", "fmi2DoStep", 100, 300)
            print(f"{n:>3} {len(lists['reals']):>6} {init:>13.0f} {get:>11.0f} {set_get:>10.0f} "
                  f"{flags:>11.0f} {step0:>10.0f} {slide:>13.0f} {slide / step0:>10.2f} "
                  f"{slide / n:>10.0f}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
