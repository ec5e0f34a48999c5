"""The image stage (``--from-images``): the camera model (``camera``), the rendered frames
(``render``), the detector and tracker (``detect``) and the stage that runs them per step (``stage``)."""
