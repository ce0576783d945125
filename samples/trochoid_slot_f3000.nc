%
O2751 (TROCHOIDAL SLOT OF SEED 000 AT F3000: THE COMPENSATION SAMPLE)
(Seed 000 Table 2: D20 end mill, slot 28 mm wide and 120 mm long, step 1.5 mm per revolution.)
(Here the slot is closed: 120 mm overall including its two round ends, along +Y from Y0 to Y120,)
(centred on X0, 10 mm deep from the top face Z0, cut in two passes of 5 mm.)
(G275 X Y = end of the slot axis, Z = floor, R = clearance plane, W = width, K = step per)
(revolution, Q = step-down per pass, P1 = climb; D omitted: the diameter of the tool in the)
(spindle comes from the machine config's tool table. gcpipe trochoid expands it.)
G17 G21 G40 G49 G54 G80 G90 G94
T2 M6 (D20 end mill: tools 2 in pipeline_configs/machines/mx330.yaml)
S4000 M3
G0 X0 Y14 Z5 (slot start S: centre of the Y0 end cap, Y0 + W/2)
G0 Z0 (the cycle starts at the top of the material: its Z is where the first pass starts)
G1 F3000 (the feed of issue 6: the slot at 3000 mm/min)
G275 X0 Y106 Z-10 R5 W28 K1.5 Q5 P1 (axis end E: centre of the Y120 end cap, Y120 - W/2)
G0 Z50
M5
M30
%
