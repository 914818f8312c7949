"""The gearboxes the tests share: loose gears driven by the shipped sample run-up, and one
whose drag follows the oil's temperature."""

#: One gear on the sample run-up, 0.2 s of sound (a short verdict).
SAMPLE_ONE_GEAR = """
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
"""
#: Two gears on the sample run-up, 0.2 s of sound each.
SAMPLE_TWO_GEARS = SAMPLE_ONE_GEAR + """
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
#: One gear under a constant order-2 excitation of 1e-3 rad, with bush and churning drag whose
#: churning part follows the viscosity of an ISO VG 68 oil (ν(100 °C) = 9 cSt) from 40 °C.
OIL_ONE_GEAR = """
[excitation]
orders = [{order = 2, amplitude_rad = 1e-3}]
engine_order = 2
harmonics = 1

[sound]
duration_s = 0.2

[oil]
iso_vg = 68
nu100_cSt = 9
temp_C = 40

[[gear]]
name = "idler"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
backlash_um = 80
drag = {bush_Nm = 0.01, churn_Nm = 0.02, at_rpm = 2000, at_temp_C = 40}
"""
