"""
amb_controller: wavelet-domain dynamics, identification, controllers and stability.

ROS-free core (thesis chapters 6-8); the ``wavelet_controller`` node maps topics onto it.

Modules
-------
basis             control (synthesis) and measured (analysis) coefficient waveforms
wavelet_dynamics  G_{p,q,a,b}(z), G^0_{p,q}(z): numerical route and Haar closed form (ch. 6)
identification    on-line Markov-parameter identification and step experiment (6.4)
inverse           truncated least-squares pseudo-inverse series B^(k) (eq. 6.35)
steady_state      steady-state prediction, proportional and moderated controllers (ch. 7)
response          prescribed transient responses alpha(z) (eq. 8.6-8.7)
transient         transient controller difference equation (eq. 8.10)
predictive        receding-horizon controller on the Markov parameters (no model inverse)
stability         gamma, criterion (8.15-8.16), (w, v) maps (fig. 8.3), exact loop poles
lti               small discrete state-space toolkit
synthesis         coefficients -> force samples, per-axis force limit
guard             divergence guard
supervisor        OFF / IDENTIFYING / ACTIVE / HOLD mode logic for the node
config            ControllerConfig: each field's default, description, range (node parameters)
pipeline          records in, one command per period out (the node's core)
status            ControllerStatus fields of a pipeline
model_file        identified model .npz

The applications that run the plant model with the controller (the in-process loop
``closed_loop``, ``plant_models``, ``amb-sim``, ``amb-compare``, ``amb-prediction``,
``acceptability``, ``acceptance``) are in :mod:`amb_apps`.
"""
