"""Planning a campaign: the candidates and the planner's inputs (`plan_inputs`), the posterior of a
design and its 95 % bound (`design_posterior`), the greedy and exchange designs (`design`), the design
robust to what the model lacks (`robust_design`), the joint tour (`joint_tour`), the robot programs
that visit it (`programs`) and the design's figures (`design_figures`)."""
