"""
amb_plant_sim: the rig of Cade (2006), chapters 2-3, as a ROS-free core.

Modules: ``elements`` and ``rotor`` (Timoshenko FE model,
eq. 2.1-2.14), ``closed_loop``/``pid``/``amb`` (AMB law and PID, eq. 2.33-2.48), ``modal`` and
``analysis`` (eq. 2.15-2.21, figures 2.4-2.17, ISO 14839-3 sensitivity), ``rotating_frame``
(eq. 2.22-2.30), ``events``/``scenario`` (faults of chapter 3 and section 5.2), ``contact``
(eq. 5.5), ``discretize``/``simulator``/``event_inputs``/``step_by_step`` (time simulation),
``calibrate`` and ``modal_cli`` (``amb-modal``).
"""
