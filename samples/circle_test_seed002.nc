%
O0002 (SEED 002 SYNCHRONOUS CIRCLE TEST)
(Suzuki et al., Int. J. Automation Technol. 2019: Section 3, Fig. 3, eqs. 1-3.)
(The workpiece contour has radius R_C = 5 mm; its centre of curvature sits R_W = 8 mm from)
(the C-axis centre, which is the work zero. C turns the table at w, so the centre of curvature)
(moves on R_W cos wt, R_W sin wt; the tool centre follows it at R_C + R_W cos wt, R_W sin wt,)
(i.e. X/Y run a circle of radius R_W around X = R_C, Y = 0 in step with C. The feed vector at the)
(cutting point then stays constant, parallel to -Y in the workpiece: F_C = w R_C, F = w R_W.)
(C is positive right-handed about +Z for the table, as in the paper's X_R = R_W cos C + R_C.)
(Six conditions from rest, each a whole number of turns lasting 4 s or more, 1 s dwell between:)
(  w [rad/s]   F = w R_W [mm/min]   F_C = w R_C [mm/min]   G93 F per turn [1/min])
(  0.5 pi       754                  471                   15)
(  1.0 pi      1508                  942                   30)
(  1.5 pi      2262                 1414                   45)
(  2.0 pi      3016                 1885                   60)
(  3.0 pi      4524                 2827                   90)
(  4.0 pi      6032                 3770                   120)
(The paper's F list: 754, 1507, 2261, 3014, 4522, 6029 mm/min.)
(Inverse time G93 keeps C and X/Y synchronous: each block lasts exactly 1/F minutes for all)
(axes; with G94 a combined linear+rotary feed would depend on the control's feed rule.)
G21 G17 G90 G40 G49 G54 G94
G0 X13. Y0 Z0 A0 C0 (start: tool centre at R_C + R_W on X, C at 0)
G93
(w = 0.5 pi rad/s = 90 deg/s: 2 turns of 4 s)
G3 X13. Y0 I-8. J0 C360. F15
G3 X13. Y0 I-8. J0 C720. F15
G94 G4 X1. (back at rest before the next condition)
G93
(w = 1.0 pi rad/s = 180 deg/s: 2 turns of 2 s)
G3 X13. Y0 I-8. J0 C1080. F30
G3 X13. Y0 I-8. J0 C1440. F30
G94 G4 X1. (back at rest before the next condition)
G93
(w = 1.5 pi rad/s = 270 deg/s: 3 turns of 1.333 s)
G3 X13. Y0 I-8. J0 C1800. F45
G3 X13. Y0 I-8. J0 C2160. F45
G3 X13. Y0 I-8. J0 C2520. F45
G94 G4 X1. (back at rest before the next condition)
G93
(w = 2.0 pi rad/s = 360 deg/s: 4 turns of 1 s)
G3 X13. Y0 I-8. J0 C2880. F60
G3 X13. Y0 I-8. J0 C3240. F60
G3 X13. Y0 I-8. J0 C3600. F60
G3 X13. Y0 I-8. J0 C3960. F60
G94 G4 X1. (back at rest before the next condition)
G93
(w = 3.0 pi rad/s = 540 deg/s: 6 turns of 0.6667 s)
G3 X13. Y0 I-8. J0 C4320. F90
G3 X13. Y0 I-8. J0 C4680. F90
G3 X13. Y0 I-8. J0 C5040. F90
G3 X13. Y0 I-8. J0 C5400. F90
G3 X13. Y0 I-8. J0 C5760. F90
G3 X13. Y0 I-8. J0 C6120. F90
G94 G4 X1. (back at rest before the next condition)
G93
(w = 4.0 pi rad/s = 720 deg/s: 8 turns of 0.5 s)
G3 X13. Y0 I-8. J0 C6480. F120
G3 X13. Y0 I-8. J0 C6840. F120
G3 X13. Y0 I-8. J0 C7200. F120
G3 X13. Y0 I-8. J0 C7560. F120
G3 X13. Y0 I-8. J0 C7920. F120
G3 X13. Y0 I-8. J0 C8280. F120
G3 X13. Y0 I-8. J0 C8640. F120
G3 X13. Y0 I-8. J0 C9000. F120
G94 G4 X1. (back at rest before the next condition)
G93
G94
M30
%
