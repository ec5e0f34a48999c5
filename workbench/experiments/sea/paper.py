"""The paper's Table 2 (bias and RMSE; angles in arcminutes, as the text makes clear although
the header says degrees), printed beside our figures. These are the paper's numbers, not ours."""

TABLE2 = {
    "geometric": {"bias": {"x": 1.98, "y": -2.79, "alpha": 0.0, "beta": 0.0},
                  "rmse": {"x": 20.7, "y": 31.0, "alpha": 0.88, "beta": 1.56}},
    "rls": {"bias": {"x": -0.74, "y": -1.1, "alpha": 0.008, "beta": 6e-4},
            "rmse": {"x": 16.9, "y": 25.2, "alpha": 0.57, "beta": 1.14}},
}
