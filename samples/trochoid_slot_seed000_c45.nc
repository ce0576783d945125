%
O2751 (TROCHOIDAL SLOT OF SEED 000, TABLE 2, IN C45 STEEL)
(Seed 000 Table 2: D20 end mill, slot 28 mm wide and 120 mm long, step 1.5 mm per revolution.)
(Here the slot is closed: 120 mm overall including its two round ends, along +Y from Y0 to Y120,)
(centred on X0, 10 mm deep from the top face Z0, cut in two passes of 5 mm.)
(G275 X Y = end of the slot axis, Z = floor, R = clearance plane, W = width, K = step per)
(revolution, Q = step-down per pass, P1 = climb; D omitted: the diameter of the tool in the)
(spindle comes from the machine config's tool table. gcpipe trochoid expands it.)
(The same slot as trochoid_slot_seed000.nc at cutting data for C45 with a D20 three-flute solid)
(carbide end mill: Tungaloy's standard conditions for carbon steel C45 up to 300 HB give vc 80 to)
(180 m/min and fz 0.10 to 0.17 mm for a 20 mm tool. S2000 is vc 126 m/min; F600 is fz 0.10 mm,)
(the low end, as the slot's radial engagement, up to 60 deg or ae 0.25 D, does not thin the chip.)
(stages/force/README.md sec. 6b; run with pipeline_configs/force_c45.yaml.)
G17 G21 G40 G49 G54 G80 G90 G94
T2 M6 (D20 end mill: tools 2 in pipeline_configs/machines/mx330.yaml)
S2000 M3
G0 X0 Y14 Z5 (slot start S: centre of the Y0 end cap, Y0 + W/2)
G0 Z0 (the cycle starts at the top of the material: its Z is where the first pass starts)
G1 F600
G275 X0 Y106 Z-10 R5 W28 K1.5 Q5 P1 (axis end E: centre of the Y120 end cap, Y120 - W/2)
G0 Z50
M5
M30
%
