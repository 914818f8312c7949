"""The gearboxes the tests share: two loose gears driven by the shipped sample run-up."""

#: Two gears on the sample run-up, 0.2 s of sound each (a short verdict).
SAMPLE_TWO_GEARS = """
[excitation]
measurement = "sample"
engine_order = 2
harmonics = 3

[sound]
duration_s = 0.2

[[gear]]
name = "5th idler"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80

[[gear]]
name = "reverse idler"
inertia_kgm2 = 2.5e-4
base_radius_m = 0.03
drag_torque_Nm = 0.03
backlash_um = 120
speed_ratio = 0.8
"""
#: The same, the reverse idler driven by a smaller gear than itself.
SAMPLE_TWO_GEARS_DRIVEN = SAMPLE_TWO_GEARS + "driver_radius_m = 0.028\n"
#: The same two gears with the default sound settings (0.5 s analysed per point).
SAMPLE_TWO_GEARS_DEFAULT_SOUND = SAMPLE_TWO_GEARS.replace("[sound]\nduration_s = 0.2\n\n", "")
