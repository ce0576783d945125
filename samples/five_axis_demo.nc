%
O1001 (FIVE-AXIS DEMO - MX-330, FANUC STYLE)
(Pocket corner with a tilted finishing pass: exercises TCP, arcs, rotary moves, dwell.)
(Units mm, tool T1 = D10 end mill, length from the tool table via H1.)
G21 G17 G40 G80 G90 G94
T1 M6
G54
G43.4 H1 (tool-centre-point on)
S8000 M3
M8
G0 X-30. Y-20. Z20. A0. C0.
G0 Z2.
G1 Z-2. F300.
G1 X20. F1200.
G3 X30. Y-10. I0. J10.
G1 Y10.
G2 X20. Y20. I-10. J0.
G1 X-20.
(tilt the table and sweep C while the tool tip stays on the edge)
G1 X-20. Y20. Z-2. A-15. C10. F900.
G1 X-10. Y20. Z-2. A-30. C25.
G1 X0. Y20. Z-2. A-30. C45.
G1 X10. Y20. Z0. A-20. C60.
G4 X0.5 (let the spindle settle before the next plunge)
G91 G1 Z-1. F200.
G90 G0 Z20. A0. C0.
M9
M5
G49
M30
%
