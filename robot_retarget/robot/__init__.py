"""Robot descriptions: configs, servo models and units, robot forward kinematics."""
